/* libFuzzer harness: the expression compiler and evaluator (engine/expr.c).
 * The input is the expression's source; variables x, y, z and a constant
 * "a" are bound; a compiled expression is evaluated over 300 points (more
 * than one chunk). Errors are expected; crashes and UB are not. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include "expr.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  if (size > 4096) return 0;
  char *src = malloc(size + 1);
  if (!src) return 0;
  memcpy(src, data, size);
  src[size] = 0;
  static const char *const vars[] = {"x", "y", "z"};
  static const char *const cn[] = {"a"};
  static const double cv[] = {0.25};
  gr_err e;
  gr_err_clear(&e);
  gr_expr *x = gr_expr_compile(src, 3, vars, 1, cn, cv, &e);
  if (x) {
    enum { N = 300 };
    double v[3][N], out[N];
    for (int i = 0; i < N; i++) {
      v[0][i] = i * 0.01 - 1;
      v[1][i] = 0.5 - i * 0.003;
      v[2][i] = (i % 7) * 0.1;
    }
    const double *vp[3] = {v[0], v[1], v[2]};
    gr_expr_eval(x, N, vp, out, &e);
    gr_expr_uses(x, 0);
    (void)gr_expr_source(x);
  }
  gr_expr_free(x);
  free(src);
  return 0;
}
