# vwe_vo: the two commands a user runs are `make demo` and `make test`.
# Everything builds in a catkin workspace inside the repository (.build/ws, git-ignored).
SHELL := /bin/bash
.SHELLFLAGS := -eo pipefail -c
ROOT := $(CURDIR)
WS ?= $(ROOT)/.build/ws
JOBS ?= 2
ENV := source $(ROOT)/scripts/ros_env.sh && export VWE_WS=$(WS)
BUILD_TYPE ?= Release
WERROR ?= OFF
CLANG_FORMAT ?= clang-format
CXX_SOURCES = git -C $(ROOT) ls-files -- '*.h' '*.cpp'
# ccache, when installed, speeds up rebuilds; its base dir (the repository's parent) lets clones
# side by side share the cache.
CCACHE ?= $(shell command -v ccache 2>/dev/null)
LAUNCHER := $(if $(CCACHE),-DCMAKE_CXX_COMPILER_LAUNCHER=$(CCACHE),)
export CCACHE_BASEDIR ?= $(abspath $(ROOT)/..)

.PHONY: all deps build test test-sanitize fuzz bench bench-live demo sequences clean help format format-check

all: build

help:
	@echo "make demo   - simulate, run the pipeline, evaluate, write out/demo (installs what is missing)"
	@echo "make test   - install what is missing, build, run every gtest and rostest"
	@echo "make test-sanitize - the core gtests built with ASan + UBSan (workspace .build/ws-asan)"
	@echo "make fuzz   - libFuzzer harnesses of the readers and conversions, FUZZ_SECONDS (60) each"
	@echo "make bench  - benchmarks, JSON in out/bench (the live replays too: bench-live)"
	@echo "make bench-live - the whole system replayed at rate 1 and 2 (CPU, drops, accuracy): out/bench/live.json"
	@echo "make build  - build only (workspace in .build/ws)"
	@echo "make format - apply .clang-format to every C++ file (format-check: only check)"
	@echo "make clean  - remove .build"

deps:
	@bash $(ROOT)/scripts/install_deps.sh

$(WS)/src/vwe_vo:
	@mkdir -p $(WS)/src
	@ln -sfn $(ROOT) $(WS)/src/vwe_vo

build: deps $(WS)/src/vwe_vo
	@echo "[build] catkin workspace $(WS) ($(BUILD_TYPE), -j$(JOBS))"
	@$(ENV) && cd $(WS) && catkin_make -DCMAKE_BUILD_TYPE=$(BUILD_TYPE) $(LAUNCHER) \
	    -DVWE_VO_WERROR=$(WERROR) -DCMAKE_EXPORT_COMPILE_COMMANDS=ON -j$(JOBS) > $(WS)/build.log 2>&1 \
	  || { tail -n 60 $(WS)/build.log; echo "[build] FAILED, full log: $(WS)/build.log"; exit 1; }
	@echo "[build] ok"

test: format-check build
	@rm -rf $(WS)/build/test_results
	@echo "[test] building and running gtests and rostests"
	@$(ENV) && cd $(WS) && catkin_make run_tests -j$(JOBS) > $(WS)/test.log 2>&1 \
	  || { tail -n 60 $(WS)/test.log; echo "[test] build of the tests FAILED"; exit 1; }
	@$(ENV) && catkin_test_results --verbose $(WS)/build/test_results > $(WS)/test_results.log 2>&1 \
	  || grep -v "^Summary" $(WS)/test_results.log | head -n 60
	@/usr/bin/python3 $(ROOT)/scripts/test_summary.py $(WS)/build/test_results

# The core gtests (test/core) under AddressSanitizer and UndefinedBehaviorSanitizer, in their own
# workspace; any report fails the run (UBSan does not recover, LeakSanitizer is on).
WS_ASAN ?= $(ROOT)/.build/ws-asan
SAN_FLAGS := -fsanitize=address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer
CORE_TESTS = $$(cd $(ROOT)/test/core && ls test_*.cpp | sed 's/\.cpp$$//')
test-sanitize: deps
	@mkdir -p $(WS_ASAN)/src && ln -sfn $(ROOT) $(WS_ASAN)/src/vwe_vo
	@echo "[test-sanitize] building the core gtests with ASan + UBSan in $(WS_ASAN)"
	@source $(ROOT)/scripts/ros_env.sh && cd $(WS_ASAN) && catkin_make -DCMAKE_BUILD_TYPE=RelWithDebInfo \
	    -DCMAKE_CXX_FLAGS="$(SAN_FLAGS)" -DCMAKE_EXE_LINKER_FLAGS="$(SAN_FLAGS)" \
	    -DCMAKE_SHARED_LINKER_FLAGS="$(SAN_FLAGS)" -j$(JOBS) $(CORE_TESTS) > $(WS_ASAN)/build.log 2>&1 \
	  || { tail -n 60 $(WS_ASAN)/build.log; echo "[test-sanitize] build FAILED, full log: $(WS_ASAN)/build.log"; exit 1; }
	@failed=0; for t in $(CORE_TESTS); do \
	    if ASAN_OPTIONS=detect_leaks=1:abort_on_error=0 UBSAN_OPTIONS=print_stacktrace=1 \
	       $(WS_ASAN)/devel/lib/vwe_vo/$$t > $(WS_ASAN)/$$t.log 2>&1; then echo "[test-sanitize] $$t ok"; \
	    else failed=$$((failed + 1)); echo "[test-sanitize] $$t FAILED:"; tail -n 40 $(WS_ASAN)/$$t.log; fi; \
	  done; [ $$failed -eq 0 ] || { echo "[test-sanitize] $$failed test binaries failed"; exit 1; }; \
	  echo "[test-sanitize] ok"

# libFuzzer (Debian's clang) with ASan + UBSan: every reader of external input and the message
# conversions (test/fuzz), FUZZ_SECONDS each; corpora grow in .build/fuzz/corpus, crashes land in
# .build/fuzz/artifacts. The generated message headers come from the catkin workspace.
FUZZ_SECONDS ?= 60
FUZZ_DIR ?= $(ROOT)/.build/fuzz
FUZZ_TARGETS ?= ecd_events ecd_calib ecd_imu tum arcs_csv config_yaml camera_yaml conversions
fuzz: deps $(WS)/src/vwe_vo
	@$(ENV) && cd $(WS) && catkin_make vwe_vo_generate_messages_cpp > $(WS)/fuzz_messages.log 2>&1 \
	  || { tail -n 30 $(WS)/fuzz_messages.log; echo "[fuzz] message generation FAILED"; exit 1; }
	@echo "[fuzz] building the harnesses with clang++ in $(FUZZ_DIR)/build"
	@mkdir -p $(FUZZ_DIR)/artifacts && cmake -S $(ROOT)/test/fuzz -B $(FUZZ_DIR)/build -DCMAKE_CXX_COMPILER=clang++ \
	    -DVWE_MSG_INCLUDE=$(WS)/devel/include > $(FUZZ_DIR)/build.log 2>&1 \
	  && cmake --build $(FUZZ_DIR)/build -j$(JOBS) >> $(FUZZ_DIR)/build.log 2>&1 \
	  || { tail -n 40 $(FUZZ_DIR)/build.log; echo "[fuzz] build FAILED, full log: $(FUZZ_DIR)/build.log"; exit 1; }
	@/usr/bin/python3 $(ROOT)/test/fuzz/make_seeds.py $(FUZZ_DIR)/seeds
	@failed=0; for t in $(FUZZ_TARGETS); do mkdir -p $(FUZZ_DIR)/corpus/$$t; \
	    if ASAN_OPTIONS=detect_leaks=1 LSAN_OPTIONS=suppressions=$(ROOT)/test/fuzz/lsan.supp UBSAN_OPTIONS=print_stacktrace=1 $(FUZZ_DIR)/build/fuzz_$$t \
	       -max_total_time=$(FUZZ_SECONDS) -timeout=10 -rss_limit_mb=2048 -max_len=4096 -print_final_stats=1 \
	       -artifact_prefix=$(FUZZ_DIR)/artifacts/$$t- $(FUZZ_DIR)/corpus/$$t $(FUZZ_DIR)/seeds/$$t \
	       > $(FUZZ_DIR)/$$t.log 2>&1; then \
	      echo "[fuzz] $$t: $$(grep -o 'stat::number_of_executed_units: *[0-9]*' $(FUZZ_DIR)/$$t.log | grep -o '[0-9]*$$') runs," \
	        "$$(grep -o 'stat::average_exec_per_sec: *[0-9]*' $(FUZZ_DIR)/$$t.log | grep -o '[0-9]*$$') exec/s, no crash"; \
	    else failed=$$((failed + 1)); echo "[fuzz] $$t FAILED (log $(FUZZ_DIR)/$$t.log):"; \
	      grep -m1 -A12 "ERROR\|runtime error\|Test unit written" $(FUZZ_DIR)/$$t.log || tail -n 20 $(FUZZ_DIR)/$$t.log; fi; \
	  done; [ $$failed -eq 0 ] || { echo "[fuzz] $$failed targets found a crash (inputs in $(FUZZ_DIR)/artifacts)"; exit 1; }

bench: build
	@$(ENV) && bash $(ROOT)/scripts/run_bench.sh $(WS) $(ROOT)/out/bench

# LIVE_ARGS: e.g. --nodelet both, --rates 1, --sequences-dir DIR (scripts/bench_live.py --help).
LIVE_ARGS ?=
bench-live: build
	@$(ENV) && /usr/bin/python3 $(ROOT)/scripts/bench_live.py --out $(ROOT)/out/bench $(LIVE_ARGS)

demo: build
	@$(ENV) && bash $(ROOT)/scripts/demo.sh

format:
	@$(CXX_SOURCES) | xargs $(CLANG_FORMAT) -i --style=file

# Fails listing the files that differ from .clang-format (run `make format` to fix them).
format-check: deps
	@bad=$$($(CXX_SOURCES) | while read -r f; do \
	    $(CLANG_FORMAT) --style=file --dry-run -Werror "$(ROOT)/$$f" >/dev/null 2>&1 || echo "$$f"; done); \
	  if [ -n "$$bad" ]; then echo "[format] these files differ from .clang-format (make format):"; \
	    echo "$$bad" | sed 's/^/  /'; exit 1; fi; echo "[format] ok"

clean:
	rm -rf $(ROOT)/.build
