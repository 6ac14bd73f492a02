# Gradus build. `make` builds build/gradus and build/gradus.so; `make test`
# and `make demo` first install missing Debian packages (as root).
PKGS      := lua5.4 yaml-0.1 readline libpng libmicrohttpd libprotobuf-c nettle
DEB_PKGS  := gcc make pkg-config liblua5.4-dev lua5.4 libyaml-dev libreadline-dev libpng-dev \
             libmicrohttpd-dev chromium curl clang libclang-rt-14-dev slurm-wlm munge \
             protobuf-c-compiler libprotobuf-c-dev protobuf-compiler nettle-dev qemu-user
CC        ?= cc
CSTD      := -std=c11 -D_POSIX_C_SOURCE=200809L -D_DEFAULT_SOURCE
WARN      := -Wall -Wextra
PKG_CFLAGS = $(shell pkg-config --cflags $(PKGS) 2>/dev/null)
PKG_LIBS   = $(shell pkg-config --libs $(PKGS) 2>/dev/null)
# -O3 vectorises the loops over grid nodes and points; -fno-math-errno lets
# sqrt be one instruction (nothing reads errno after a math call): together
# 10 % less CPU on the continuous-grading job, its output byte for byte the
# same (doc/performance.md)
CFLAGS    ?= -O3 -g -fno-math-errno
# The vector unit: where the building machine has x86-64-v3 (AVX, AVX2, BMI1/2,
# F16C, FMA, LZCNT, MOVBE, XSAVE in /proc/cpuinfo), the engine is built for it
# and -O3 vectorises four doubles at a time instead of two (7 % less CPU on the
# continuous job; no a*b+c is fused in ISO C mode, doc/performance.md). Such a
# build stops with a message on a processor without them (engine/vecmath.c);
# `make ARCH=` builds for any x86-64.
V3_CPU    := avx avx2 bmi1 bmi2 f16c fma abm movbe xsave
ifeq ($(origin ARCH),undefined)
ARCH      := $(shell [ "$$(uname -m)" = x86_64 ] || exit 0; for x in $(V3_CPU); do grep -qw $$x /proc/cpuinfo 2>/dev/null || exit 0; done; echo -march=x86-64-v3)
endif
ALL_CFLAGS = $(CSTD) $(WARN) $(CFLAGS) $(ARCH) -fPIC -pthread -Iengine -Ibuild/gen $(PKG_CFLAGS)
# objects are rebuilt when the flags change (ARCH, CFLAGS)
FLAGS_STAMP := build/flags
$(shell mkdir -p build && echo '$(ALL_CFLAGS)' > build/flags.new && { cmp -s build/flags.new $(FLAGS_STAMP) && rm -f build/flags.new || mv build/flags.new $(FLAGS_STAMP); })
# libmvec: glibc's vector math (vecmath.c), on x86-64
MVEC      := $(if $(filter x86_64,$(shell uname -m)),-lmvec)
LIBS       = $(PKG_LIBS) $(MVEC) -lm -pthread -ldl
FUZZ_CC   ?= clang
FUZZ_HAVE := $(shell command -v $(FUZZ_CC) >/dev/null 2>&1 && echo yes)
SAN        = -O1 -g -fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined

ALL_SRC   := $(wildcard engine/*.c)
CORE_SRC  := $(filter-out engine/bind%.c engine/main.c,$(ALL_SRC))
BIND_SRC  := $(filter engine/bind%.c,$(ALL_SRC))
# OVF messages: engine/ovf/ovf.proto compiled by protoc-c into build/gen
GEN_HDR   := build/gen/ovf.pb-c.h
HDRS      := $(wildcard engine/*.h) $(GEN_HDR)
CORE_OBJ  := $(CORE_SRC:engine/%.c=build/obj/%.o) build/obj/ovf.pb-c.o
BIND_OBJ  := $(BIND_SRC:engine/%.c=build/obj/%.o)
SAN_OBJ   := $(CORE_SRC:engine/%.c=build/asan/obj/%.o) build/asan/obj/ovf.pb-c.o
SAN_BIND  := $(BIND_SRC:engine/%.c=build/asan/obj/%.o) build/asan/obj/main.o
CTESTS    := $(patsubst tests/c/%.c,%,$(wildcard tests/c/test_*.c))

.PHONY: all deps check-deps test test-run demo demo-run bench clean ctests fuzz fuzz-build
all: check-deps build/gradus build/gradus.so

# Install what is missing (fresh Debian 12, as root).
deps:
	@missing=""; for p in $(DEB_PKGS); do dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	if [ -n "$$missing" ]; then \
	  if [ "$$(id -u)" != 0 ]; then echo "gradus: missing Debian packages:$$missing; run as root: apt-get install -y$$missing" >&2; exit 1; fi; \
	  echo "gradus: installing$$missing"; \
	  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $$missing) >/dev/null || exit 1; \
	fi

check-deps:
	@pkg-config --exists $(PKGS) 2>/dev/null || { echo "gradus: missing libraries; install them with: apt-get install -y $(DEB_PKGS)  (or run 'make deps' as root)" >&2; exit 1; }

build/obj/%.o: engine/%.c $(HDRS) $(FLAGS_STAMP) | build/obj
	$(CC) $(ALL_CFLAGS) -c $< -o $@
build/asan/obj/%.o: engine/%.c $(HDRS) $(FLAGS_STAMP) | build/asan/obj
	$(CC) $(ALL_CFLAGS) $(SAN) -c $< -o $@
build/gen/ovf.pb-c.c build/gen/ovf.pb-c.h: engine/ovf/ovf.proto
	@mkdir -p build/gen
	protoc-c --c_out=build/gen -Iengine/ovf $<
build/obj/ovf.pb-c.o: build/gen/ovf.pb-c.c $(GEN_HDR) $(FLAGS_STAMP) | build/obj
	$(CC) $(ALL_CFLAGS) -c $< -o $@
build/asan/obj/ovf.pb-c.o: build/gen/ovf.pb-c.c $(GEN_HDR) $(FLAGS_STAMP) | build/asan/obj
	$(CC) $(ALL_CFLAGS) $(SAN) -c $< -o $@
build/obj build/asan/obj build/tests build/asan/tests:
	mkdir -p $@

build/gradus: $(CORE_OBJ) $(BIND_OBJ) build/obj/main.o
	$(CC) -o $@ $^ $(LIBS) -Wl,-E
build/gradus.so: $(CORE_OBJ) $(BIND_OBJ)
	$(CC) -shared -o $@ $^ $(filter-out -llua5.4,$(LIBS))

build/tests/%: tests/c/%.c tests/c/check.h $(CORE_OBJ) | build/tests
	$(CC) $(ALL_CFLAGS) -o $@ $< $(CORE_OBJ) $(LIBS)
build/asan/tests/%: tests/c/%.c tests/c/check.h $(SAN_OBJ) | build/asan/tests
	$(CC) $(ALL_CFLAGS) $(SAN) -o $@ $< $(SAN_OBJ) $(LIBS)

# the host itself under the sanitizers, for the pipeline test (tests/sh/test_sanitized.sh)
build/gradus-asan: $(SAN_OBJ) $(SAN_BIND)
	$(CC) $(SAN) -o $@ $^ $(LIBS) -Wl,-E

ctests: $(CTESTS:%=build/tests/%) $(CTESTS:%=build/asan/tests/%) build/gradus-asan

test: deps
	@$(MAKE) --no-print-directory test-run
# the benchmarks are built (not run) with the tests, so that an API change cannot leave one
# uncompilable while make bench skips it
BENCH_C   := $(wildcard bench/bench_*.c)
BENCH_BIN := $(BENCH_C:bench/%.c=build/bench/%)
test-run: all ctests $(BENCH_BIN) $(if $(FUZZ_HAVE),fuzz-build)
	@bash tests/run.sh

demo: deps
	@$(MAKE) --no-print-directory demo-run
demo-run: all
	./build/gradus run recipes/demo.lua -o out/demo.cli --stats out/demo.yaml
	./build/gradus view out/demo.cli -o out/demo.html

bench: all
	@bash bench/run.sh

clean:
	rm -rf build

# Benchmarks: bench/bench_*.c are C programs linked with the core.
build/bench/%: bench/%.c $(CORE_OBJ)
	@mkdir -p build/bench
	$(CC) $(ALL_CFLAGS) -O3 -o $@ $< $(CORE_OBJ) $(LIBS)
.SECONDARY:

# Fuzzing: libFuzzer harnesses tests/fuzz/fuzz_*.c built with Debian's clang
# under ASan+UBSan; `make fuzz` runs each for FUZZ_SECONDS on its corpus
# tests/fuzz/<name>/ (new inputs go to build/fuzz/corpus/<name>/);
# `make test` replays the corpora for a fixed number of runs (tests/sh/test_fuzz.sh).
FUZZ_SECONDS ?= 60
FUZZ_SAN      = -g -O1 -fno-omit-frame-pointer -fsanitize=address,undefined -fno-sanitize-recover=undefined
FUZZERS      := $(patsubst tests/fuzz/fuzz_%.c,%,$(wildcard tests/fuzz/fuzz_*.c))
FUZZ_OBJ     := $(CORE_SRC:engine/%.c=build/fuzz/obj/%.o) $(BIND_SRC:engine/%.c=build/fuzz/obj/%.o) build/fuzz/obj/ovf.pb-c.o
build/fuzz/obj:
	mkdir -p $@
build/fuzz/obj/%.o: engine/%.c $(HDRS) | build/fuzz/obj
	$(FUZZ_CC) $(CSTD) $(WARN) $(FUZZ_SAN) -fsanitize=fuzzer-no-link -pthread -Iengine -Ibuild/gen $(PKG_CFLAGS) -c $< -o $@
build/fuzz/obj/ovf.pb-c.o: build/gen/ovf.pb-c.c $(GEN_HDR) | build/fuzz/obj
	$(FUZZ_CC) $(CSTD) $(WARN) $(FUZZ_SAN) -fsanitize=fuzzer-no-link -pthread -Iengine -Ibuild/gen $(PKG_CFLAGS) -c $< -o $@
build/fuzz/fuzz_%: tests/fuzz/fuzz_%.c $(FUZZ_OBJ)
	$(FUZZ_CC) $(CSTD) $(WARN) $(FUZZ_SAN) -fsanitize=fuzzer -pthread -Iengine -Ibuild/gen $(PKG_CFLAGS) -o $@ $< $(FUZZ_OBJ) $(LIBS)
fuzz-build: $(FUZZERS:%=build/fuzz/fuzz_%)
fuzz: check-deps fuzz-build
	@bash tests/fuzz/run.sh $(FUZZ_SECONDS) $(FUZZERS)
