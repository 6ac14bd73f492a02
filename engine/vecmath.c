/* vecmath.c: see vecmath.h. The vector functions are libmvec's, named by
 * the x86-64 vector function ABI (_ZGV, b: 2 values in SSE registers, d: 4
 * in AVX2 ones, N: no mask, v: one vector argument); the AVX2 ones only
 * where the processor has AVX2, the SSE ones (x86-64's baseline) elsewhere. */
#include "vecmath.h"
#include <math.h>
#include <unistd.h>

#if defined(__x86_64__) && defined(__GNUC__) && defined(__AVX2__)
/* A build for x86-64-v3 (the Makefile's ARCH, where the building machine has
 * it) checks the processor before anything else runs: without AVX2, FMA or
 * BMI2 it says so and exits 1 instead of dying of an illegal instruction.
 * This function itself is compiled for plain x86-64. */
__attribute__((constructor, target("arch=x86-64"))) static void gr_cpu_level_check(void) {
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") && __builtin_cpu_supports("bmi2")) return;
  static const char msg[] = "gradus: this build uses x86-64-v3 instructions (AVX2, FMA, BMI2), which this processor "
                            "lacks; rebuild it on this machine with: make clean && make ARCH=\n";
  (void)!write(2, msg, sizeof msg - 1);
  _exit(1);
}
#endif

#if defined(__x86_64__) && defined(__GLIBC__)
#include <immintrin.h>

#define VECFN(NAME, F)                                                                  \
  __m128d _ZGVbN2v_##F(__m128d);                                                        \
  __attribute__((target("avx2"))) __m256d _ZGVdN4v_##F(__m256d);                       \
  __attribute__((target("avx2"))) static size_t NAME##_avx2(size_t n, double *a) {     \
    size_t i = 0;                                                                       \
    for (; i + 4 <= n; i += 4) _mm256_storeu_pd(a + i, _ZGVdN4v_##F(_mm256_loadu_pd(a + i))); \
    return i;                                                                           \
  }                                                                                     \
  void NAME(size_t n, double *a) {                                                      \
    size_t i = __builtin_cpu_supports("avx2") ? NAME##_avx2(n, a) : 0;                  \
    for (; i + 2 <= n; i += 2) _mm_storeu_pd(a + i, _ZGVbN2v_##F(_mm_loadu_pd(a + i)));  \
    for (; i < n; i++) a[i] = F(a[i]);                                                  \
  }

#else

#define VECFN(NAME, F)                                                                  \
  void NAME(size_t n, double *a) {                                                      \
    for (size_t i = 0; i < n; i++) a[i] = F(a[i]);                                      \
  }

#endif

VECFN(gr_vsin, sin)
VECFN(gr_vcos, cos)
VECFN(gr_vexp, exp)
VECFN(gr_vlog, log)
