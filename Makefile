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

.PHONY: all deps build test bench demo sequences clean help format format-check

all: build

help:
	@echo "make demo   - simulate, run the pipeline, evaluate, write out/demo (installs what is missing)"
	@echo "make test   - install what is missing, build, run every gtest and rostest"
	@echo "make bench  - benchmarks, JSON in out/bench"
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
	@$(ENV) && cd $(WS) && catkin_make -DCMAKE_BUILD_TYPE=$(BUILD_TYPE) \
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

bench: build
	@$(ENV) && bash $(ROOT)/scripts/run_bench.sh $(WS) $(ROOT)/out/bench

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
