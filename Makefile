# SPDX-License-Identifier: BSD-3-Clause
# The two set-up commands of the README: `make demo` and `make test`. Both install what is missing.
JOBS        ?= $(shell nproc)
BUILD       ?= build
BUILD_ASAN  ?= build-asan
BUILD_TSAN  ?= build-tsan
BUILD_TYPE  ?= RelWithDebInfo
# RelWithDebInfo with line tables only (-g1): backtraces and sanitizer reports keep file:line, and
# the builds of `make test` compile about 17 % faster than with full -g (doc/BENCHMARK.md,
# thirtieth session). For a debugger's variables: make BUILD_TYPE=Debug, or DEBUG_FLAGS="-O2 -g".
DEBUG_FLAGS ?= -O2 -g1 -DNDEBUG
# The sanitizer build at -O1, as ASan's authors advise: it compiles in 0.77x the time of -O2 and its
# tests take 1.05x as long (doc/BENCHMARK.md, thirty-first session). Compiled by clang, whose
# ASan + UBSan code compiles in about 0.65x gcc's time (doc/BENCHMARK.md, fiftieth session); the
# normal build stays with gcc, whose bits the regression digests hold.
ASAN_FLAGS  ?= -O1 -g1 -DNDEBUG
ASAN_CXX    ?= clang++-14
# The test programs' own sources in the normal build (tests/CMakeLists.txt).
TEST_FLAGS  ?= -O1
DATA        ?= $(abspath ../shared/data)
DEMO_INPUT  ?=
DEMO_OUT    ?= $(abspath demo-out)

.PHONY: all deps build test test-asan test-tsan demo benchmark fuzz install clean format

all: build

deps:
	@./cmake/install-deps.sh

$(BUILD)/CMakeCache.txt:
	cmake -S . -B $(BUILD) -DCMAKE_BUILD_TYPE=$(BUILD_TYPE) -DCLEANMAP_BUILD_TESTS=ON \
	  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="$(DEBUG_FLAGS)" -DCLEANMAP_TEST_CXX_FLAGS="$(TEST_FLAGS)" \
	  -DCLEANMAP_SHARED_DATA_DIR=$(DATA)

build: deps $(BUILD)/CMakeCache.txt
	cmake --build $(BUILD) -j $(JOBS)

# Every test in the normal build, then the unit tests once more under ASan + UBSan.
# Each phase's start is printed with the time: where CI's minutes go.
test: build
	@echo "make test: $$(date +%T) the normal build's tests"
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS)
	$(MAKE) --no-print-directory test-asan

test-asan:
	@echo "make test: $$(date +%T) the sanitizer build"
	@./cmake/install-deps.sh sanitize
	cmake -S . -B $(BUILD_ASAN) -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCLEANMAP_SANITIZE=ON \
	  -DCMAKE_CXX_COMPILER=$(ASAN_CXX) \
	  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="$(ASAN_FLAGS)" -DCLEANMAP_BUILD_TESTS=ON \
	  -DCLEANMAP_SHARED_DATA_DIR=$(DATA)
	cmake --build $(BUILD_ASAN) -j $(JOBS)
	@echo "make test: $$(date +%T) the sanitizer build's unit tests"
	cd $(BUILD_ASAN) && ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 \
	  ctest --output-on-failure -j $(JOBS) -L unit
	@echo "make test: $$(date +%T) done"

# Not part of `make test`: the unit tests (the app's runs included) under ThreadSanitizer, clang,
# only cleanmap's code instrumented; cmake/tsan.supp names the Debian libraries' own reports.
# About 2 minutes to build and 8.5 to run on two cores; TSAN_LABELS='unit|regression|sim' for more.
TSAN_LABELS ?= unit
test-tsan:
	@./cmake/install-deps.sh sanitize
	cmake -S . -B $(BUILD_TSAN) -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCLEANMAP_TSAN=ON \
	  -DCMAKE_CXX_COMPILER=$(ASAN_CXX) \
	  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="$(ASAN_FLAGS)" -DCLEANMAP_BUILD_TESTS=ON \
	  -DCLEANMAP_SHARED_DATA_DIR=$(DATA)
	cmake --build $(BUILD_TSAN) -j $(JOBS)
	cd $(BUILD_TSAN) && TSAN_OPTIONS="suppressions=$(abspath cmake/tsan.supp) second_deadlock_stack=1" \
	  ctest --output-on-failure -j $(JOBS) -L '$(TSAN_LABELS)'

demo: build
	@./cmake/demo.sh "$(BUILD)" "$(DEMO_INPUT)" "$(DEMO_OUT)"

benchmark: deps
	cmake -S . -B build-release -DCMAKE_BUILD_TYPE=Release -DCLEANMAP_BUILD_BENCHMARKS=ON \
	  -DCLEANMAP_BUILD_TESTS=OFF
	cmake --build build-release -j $(JOBS)
	./cmake/benchmark.sh build-release $(DATA) $(abspath build-release/benchmark) $(or $(ROC),1)

# libFuzzer on every reader (tests/fuzz), FUZZ_SECONDS per target (clang from Debian, build-fuzz/).
# `make test` replays the committed corpus only; this searches for new findings.
fuzz:
	@./cmake/install-deps.sh fuzz
	CC=clang-14 CXX=clang++-14 cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo \
	  -DCLEANMAP_FUZZ=ON
	cmake --build build-fuzz -j $(JOBS)
	./cmake/fuzz.sh build-fuzz $(or $(FUZZ_SECONDS),60) $(FUZZ_TARGETS)

install: build
	cmake --install $(BUILD) --prefix $(or $(PREFIX),/usr/local)

# The pinned formatter (Debian 12's clang-format-14); `make test` fails on unformatted code.
format: deps
	clang-format-14 -i --style=file $$(git ls-files '*.cpp' '*.h')

clean:
	rm -rf $(BUILD) $(BUILD_ASAN) $(BUILD_TSAN) build-release build-fuzz $(DEMO_OUT)
