/* test_expr.c: the expression compiler against the same formulas written in
 * C, operator precedence and associativity, error messages and NaN checks. */
#include <stdlib.h>
#include <string.h>
#include "check.h"
#include "expr.h"

static const char *const XYZ[3] = {"x", "y", "z"};

static double rnd(double lo, double hi) { return lo + (hi - lo) * (rand() / (double)RAND_MAX); }

/* Evaluate src at one point (x, y, z); returns the gr_err code. */
static int eval1(const char *src, double x, double y, double z, double *out, gr_err *e) {
  gr_expr *ex = gr_expr_compile(src, 3, XYZ, 0, NULL, NULL, e);
  if (!ex) return e->code;
  const double *v[3] = {&x, &y, &z};
  int rc = gr_expr_eval(ex, 1, v, out, e);
  gr_expr_free(ex);
  return rc;
}

typedef double (*cfn)(double x, double y, double z);
static double f1(double x, double y, double z) { return sin(x) * cos(y) + tan(z / 4); }
static double f2(double x, double y, double z) { return 2 + 3 * x - y / 4 * z; }
static double f3(double x, double y, double z) { (void)z; return -(x * x) + pow(2, pow(3, 0.5)) * y; }
static double f4(double x, double y, double z) { return sqrt(x * x + y * y + z * z) - 3; }
static double f5(double x, double y, double z) { return exp(-fabs(x)) + log(1 + y * y) + floor(z); }
static double f6(double x, double y, double z) { return fmin(x, y) - fmax(y, z) + atan2(y, x) + atan(z); }
static double f7(double x, double y, double z) { (void)z; return asin(x / 10) + acos(y / 10) * M_PI; }
static double f8(double x, double y, double z) { return x - y - z - 1; }
static double f9(double x, double y, double z) { (void)y; (void)z; return x / 2 / 4; }
static double f10(double x, double y, double z) { return -pow(fabs(x), -y / 10) + -(-z); }

TEST(matches_c_formulas) {
  struct { const char *src; cfn f; } cases[] = {
    {"sin(x)*cos(y) + tan(z/4)", f1},
    {"2 + 3*x - y/4*z", f2},
    {"-x^2 + 2^3^0.5*y", f3},
    {"sqrt(x^2 + y^2 + z^2) - 3", f4},
    {"exp(-abs(x)) + log(1 + y*y) + floor(z)", f5},
    {"min(x, y) - max(y, z) + atan(y, x) + atan(z)", f6},
    {"asin(x/10) + acos(y/10)*pi", f7},
    {"x - y - z - 1", f8},
    {"x / 2 / 4", f9},
    {"-abs(x)^(-y/10) + -(-z)", f10},
  };
  srand(1);
  enum { N = 1000 };
  double *x = malloc(N * sizeof *x), *y = malloc(N * sizeof *y), *z = malloc(N * sizeof *z);
  double *out = malloc(N * sizeof *out);
  for (int i = 0; i < N; i++) { x[i] = rnd(-5, 5); y[i] = rnd(-5, 5); z[i] = rnd(-5, 5); }
  const double *v[3] = {x, y, z};
  for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
    if (!cases[c].f) continue;
    gr_err e = {0};
    gr_expr *ex = gr_expr_compile(cases[c].src, 3, XYZ, 0, NULL, NULL, &e);
    CHECK(ex != NULL, "%s: %s", cases[c].src, e.msg);
    if (!ex) continue;
    int rc = gr_expr_eval(ex, N, v, out, &e);
    CHECK(rc == GR_OK, "%s: %s", cases[c].src, e.msg);
    int bad = 0;
    for (int i = 0; i < N && rc == GR_OK; i++) {
      double want = cases[c].f(x[i], y[i], z[i]);
      if (fabs(out[i] - want) > 1e-12 * (1 + fabs(want))) bad++;
    }
    CHECK(bad == 0, "%s: %d of %d points differ", cases[c].src, bad, N);
    gr_expr_free(ex);
  }
  free(x); free(y); free(z); free(out);
}

TEST(precedence_and_associativity) {
  gr_err e = {0};
  double v;
  CHECK(eval1("-2^2", 0, 0, 0, &v, &e) == GR_OK && v == -4, "-2^2 = %g", v);
  CHECK(eval1("2^3^2", 0, 0, 0, &v, &e) == GR_OK && v == 512, "2^3^2 = %g", v);
  CHECK(eval1("2^-1", 0, 0, 0, &v, &e) == GR_OK && v == 0.5, "2^-1 = %g", v);
  CHECK(eval1("(-2)^2", 0, 0, 0, &v, &e) == GR_OK && v == 4, "(-2)^2 = %g", v);
  CHECK(eval1("1 - 2 - 3", 0, 0, 0, &v, &e) == GR_OK && v == -4, "1-2-3 = %g", v);
  CHECK(eval1("8/2/2", 0, 0, 0, &v, &e) == GR_OK && v == 2, "8/2/2 = %g", v);
  CHECK(eval1("1 + 2*3", 0, 0, 0, &v, &e) == GR_OK && v == 7, "1+2*3 = %g", v);
  CHECK(eval1("--x", 3, 0, 0, &v, &e) == GR_OK && v == 3, "--x = %g", v);
  CHECK(eval1("-x^2", 3, 0, 0, &v, &e) == GR_OK && v == -9, "-x^2 = %g", v);
  CHECK(eval1("2*-y", 0, 3, 0, &v, &e) == GR_OK && v == -6, "2*-y = %g", v);
  CHECK(eval1("1.5e1 + .5 + 2E-1", 0, 0, 0, &v, &e) == GR_OK && fabs(v - 15.7) < 1e-14, "numbers = %g", v);
  CHECK(eval1("pi", 0, 0, 0, &v, &e) == GR_OK && v == M_PI, "pi = %g", v);
  CHECK(eval1("  z  ", 0, 0, 7, &v, &e) == GR_OK && v == 7, "spaces = %g", v);
}

TEST(constants_and_uses) {
  const char *vars[2] = {"u", "w"};
  const char *cn[1] = {"L"};
  double cv[1] = {2.5};
  gr_err e = {0};
  gr_expr *ex = gr_expr_compile("L*u + pi", 2, vars, 1, cn, cv, &e);
  CHECK(ex != NULL, "%s", e.msg);
  if (!ex) return;
  CHECK(gr_expr_uses(ex, 0), "uses u");
  CHECK(!gr_expr_uses(ex, 1), "does not use w");
  CHECK(strcmp(gr_expr_source(ex), "L*u + pi") == 0, "source");
  double u = 2, w = 0, out;
  const double *v[2] = {&u, &w};
  CHECK(gr_expr_eval(ex, 1, v, &out, &e) == GR_OK, "%s", e.msg);
  CHECK_NEAR(out, 5 + M_PI, 1e-15);
  gr_expr_free(ex);
  gr_expr_free(NULL);
  /* smooth: no abs, min, max or floor (kinks and steps) */
  const char *smooth[] = {"sin(u)*cos(w) + sqrt(2 + u^2)", "exp(-u) / (1 + w^2)"};
  const char *kinked[] = {"abs(u)", "min(u, w) + 1", "max(u, 0.1)", "floor(u*4)/4", "0.1 + 0*abs(w)"};
  for (int k = 0; k < 2; k++) {
    ex = gr_expr_compile(smooth[k], 2, vars, 1, cn, cv, &e);
    CHECK(ex && gr_expr_smooth(ex), "'%s' is smooth", smooth[k]);
    gr_expr_free(ex);
  }
  for (int k = 0; k < 5; k++) {
    ex = gr_expr_compile(kinked[k], 2, vars, 1, cn, cv, &e);
    CHECK(ex && !gr_expr_smooth(ex), "'%s' is not smooth", kinked[k]);
    gr_expr_free(ex);
  }
}

TEST(error_messages) {
  gr_err e = {0};
  double v;
  CHECK(eval1("sin(x", 0, 0, 0, &v, &e) == GR_EPARSE, "code %d", e.code);
  CHECK(strcmp(e.msg, "expression 'sin(x' col 6: expected ')'") == 0, "got '%s'", e.msg);
  CHECK(eval1("x + foo", 0, 0, 0, &v, &e) != GR_OK, "unknown name");
  CHECK(strstr(e.msg, "col 5") && strstr(e.msg, "'foo'") && strstr(e.msg, "x, y, z"), "got '%s'", e.msg);
  CHECK(eval1("bar(x)", 0, 0, 0, &v, &e) != GR_OK && strstr(e.msg, "col 1") && strstr(e.msg, "'bar'"),
        "got '%s'", e.msg);
  CHECK(eval1("min(x)", 0, 0, 0, &v, &e) != GR_OK && strstr(e.msg, "min() takes 2"), "got '%s'", e.msg);
  CHECK(eval1("sin(x, y)", 0, 0, 0, &v, &e) != GR_OK && strstr(e.msg, "sin() takes 1"), "got '%s'", e.msg);
  CHECK(eval1("x +", 0, 0, 0, &v, &e) != GR_OK && strstr(e.msg, "col 4"), "got '%s'", e.msg);
  CHECK(eval1("x y", 0, 0, 0, &v, &e) != GR_OK && strstr(e.msg, "col 3"), "got '%s'", e.msg);
  CHECK(eval1("", 0, 0, 0, &v, &e) != GR_OK, "empty");
  CHECK(eval1("2 * (x", 0, 0, 0, &v, &e) != GR_OK && strstr(e.msg, "col 7: expected ')'"), "got '%s'", e.msg);
  CHECK(eval1("1e+", 0, 0, 0, &v, &e) != GR_OK && strstr(e.msg, "exponent"), "got '%s'", e.msg);
  CHECK(eval1("sin", 0, 0, 0, &v, &e) != GR_OK && strstr(e.msg, "expected '('"), "got '%s'", e.msg);
  CHECK(eval1("x $ 2", 0, 0, 0, &v, &e) != GR_OK && strstr(e.msg, "col 3"), "got '%s'", e.msg);
  /* nesting far beyond the limit fails cleanly instead of overflowing */
  char deep[2100];
  memset(deep, '(', 1000); deep[1000] = 'x'; memset(deep + 1001, ')', 1000); deep[2001] = 0;
  CHECK(eval1(deep, 0, 0, 0, &v, &e) != GR_OK && strstr(e.msg, "nested"), "deep: '%.60s'", e.msg);
}

TEST(nan_detection) {
  gr_err e = {0};
  double v;
  CHECK(eval1("log(-1)", 1, 2, 3, &v, &e) == GR_ENUM, "code %d", e.code);
  CHECK(strstr(e.msg, "expression 'log(-1)' gave nan at x=1, y=2, z=3") != NULL, "got '%s'", e.msg);
  CHECK(eval1("1/x", 0, 2, 3, &v, &e) == GR_ENUM && strstr(e.msg, "gave inf"), "got '%s'", e.msg);
  CHECK(eval1("sqrt(x)", -4, 0, 0, &v, &e) == GR_ENUM && strstr(e.msg, "x=-4"), "got '%s'", e.msg);
  /* the bad point is named even deep into a batch */
  enum { N = 700 };
  double x[N], y[N], z[N], out[N];
  for (int i = 0; i < N; i++) { x[i] = i; y[i] = 0; z[i] = 0; }
  x[600] = -1;
  const double *vv[3] = {x, y, z};
  gr_expr *ex = gr_expr_compile("sqrt(x)", 3, XYZ, 0, NULL, NULL, &e);
  CHECK(ex && gr_expr_eval(ex, N, vv, out, &e) == GR_ENUM && strstr(e.msg, "x=-1,"), "got '%s'", e.msg);
  gr_expr_free(ex);
}

TEST(deep_stack) {
  /* needs more stack slots than the on-stack buffer holds */
  char src[4000] = "";
  for (int i = 0; i < 40; i++) strcat(src, "(x+");
  strcat(src, "1");
  for (int i = 0; i < 40; i++) strcat(src, ")");
  gr_err e = {0};
  double v;
  CHECK(eval1(src, 0.5, 0, 0, &v, &e) == GR_OK, "%s", e.msg);
  CHECK_NEAR(v, 21, 1e-12);
}

int main(void) {
  RUN(matches_c_formulas);
  RUN(precedence_and_associativity);
  RUN(constants_and_uses);
  RUN(error_messages);
  RUN(nan_detection);
  RUN(deep_stack);
  DONE();
}
