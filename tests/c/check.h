/* check.h: a tiny test harness for the C tests. Each TEST is a function; a
 * CHECK that fails prints where and why and marks the test failed. main()
 * runs the tests with RUN() and ends with DONE(). The runner (tests/run.sh)
 * counts the "PASS " and "FAIL " lines. */
#ifndef GR_CHECK_H
#define GR_CHECK_H
#include <math.h>
#include <stdio.h>

static int check_failed_, check_total_fail_;

#define TEST(name) static void name(void)
#define CHECK(cond, ...)                                                    \
  do {                                                                      \
    if (!(cond)) {                                                          \
      check_failed_ = 1;                                                    \
      printf("    %s:%d: check failed: %s: ", __FILE__, __LINE__, #cond);   \
      printf(__VA_ARGS__);                                                  \
      printf("\n");                                                         \
    }                                                                       \
  } while (0)
#define CHECK_NEAR(a, b, tol)                                               \
  do {                                                                      \
    double a_ = (a), b_ = (b), t_ = (tol);                                  \
    CHECK(fabs(a_ - b_) <= t_, "%s = %.10g, %s = %.10g, |diff| %.3g > %.3g", \
          #a, a_, #b, b_, fabs(a_ - b_), t_);                              \
  } while (0)
#define RUN(fn)                                                             \
  do {                                                                      \
    check_failed_ = 0;                                                      \
    fn();                                                                   \
    printf("%s %s: %s\n", check_failed_ ? "FAIL" : "PASS", __FILE__, #fn); \
    fflush(stdout);                                                         \
    check_total_fail_ += check_failed_;                                     \
  } while (0)
#define DONE() return check_total_fail_ ? 1 : 0

#endif
