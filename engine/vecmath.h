/* vecmath.h: sine, cosine, exponential and logarithm of many values at once,
 * in place, from glibc's vector math library (libmvec: 4 values a call with
 * AVX2, 2 without; within 4 ulp, as its manual states) on x86-64, and from
 * libm one value at a time elsewhere. For the thickness expressions, which
 * evaluate hundreds of points a call. */
#ifndef GR_VECMATH_H
#define GR_VECMATH_H
#include <stddef.h>

void gr_vsin(size_t n, double *a);
void gr_vcos(size_t n, double *a);
void gr_vexp(size_t n, double *a);
void gr_vlog(size_t n, double *a);

#endif
