/* expr.h: arithmetic expressions compiled from strings into an instruction
 * list and evaluated over arrays of points (no Lua, no per-point parsing).
 * Grammar: numbers, named variables, named constants, + - * / ^ (right assoc.),
 * unary -, parentheses, and the functions
 * sin cos tan asin acos atan exp log sqrt abs min max floor (doc/contract.md s.3).
 * Thread-safe: a compiled expression is immutable. */
#ifndef GR_EXPR_H
#define GR_EXPR_H
#include "common.h"

typedef struct gr_expr gr_expr;

/* Compile `src`. Variables are given by name (their values come per point in
 * gr_expr_eval); constants are bound now (pi is always bound). Unknown names,
 * syntax errors and wrong argument counts fail with the column, e.g.
 * "expression 'sin(x' col 6: expected ')'". */
gr_expr *gr_expr_compile(const char *src, int nvars, const char *const *vars,
                         int nconst, const char *const *cnames,
                         const double *cvals, gr_err *e);
void gr_expr_free(gr_expr *x); /* NULL is fine */
const char *gr_expr_source(const gr_expr *x);
/* Whether the expression reads variable i. */
int gr_expr_uses(const gr_expr *x, int i);
/* Whether the expression is smooth wherever it is finite: none of abs, min,
 * max, floor (whose kinks and steps no sample of their neighbourhood shows). */
int gr_expr_smooth(const gr_expr *x);

/* out[k] = value at point k, vars[i][k] the i-th variable. A NaN or infinite
 * result fails with GR_ENUM naming the expression and the point's variables. */
int gr_expr_eval(const gr_expr *x, size_t n, const double *const *vars,
                 double *out, gr_err *e);

#endif
