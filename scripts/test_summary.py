#!/usr/bin/python3
"""Counts test cases in the JUnit XML files that catkin's test runs wrote and prints the plain
closing line `N passed, N failed` (CI reads it). Exit status 1 on any failure or error, on a
missing result file, or when no test ran at all."""
import glob
import os
import sys
import xml.etree.ElementTree as ET


def main():
    root = sys.argv[1] if len(sys.argv) > 1 else "."
    files = sorted(glob.glob(os.path.join(root, "**", "*.xml"), recursive=True))
    passed, failed, skipped = 0, 0, 0
    failures = []
    for path in files:
        try:
            tree = ET.parse(path)
        except ET.ParseError as err:
            failed += 1
            failures.append("%s: unreadable JUnit XML (%s)" % (path, err))
            continue
        for case in tree.iter("testcase"):
            name = "%s.%s" % (case.get("classname", "?"), case.get("name", "?"))
            if case.find("failure") is not None or case.find("error") is not None:
                failed += 1
                failures.append("%s (%s)" % (name, os.path.basename(path)))
            elif case.find("skipped") is not None or case.get("status") == "notrun":
                skipped += 1
            else:
                passed += 1
    for f in failures:
        print("FAILED: " + f)
    line = "%d passed, %d failed" % (passed, failed)
    if skipped:
        line += ", %d skipped" % skipped
    print(line)
    if not files:
        print("no JUnit XML found under %s" % root, file=sys.stderr)
        return 1
    return 1 if failed or passed == 0 else 0


if __name__ == "__main__":
    sys.exit(main())
