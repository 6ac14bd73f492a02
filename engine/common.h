/* common.h: error reporting, growable arrays and atomic file output shared by
 * every engine file. The core never prints or exits: functions return a status
 * code and fill a gr_err. */
#ifndef GR_COMMON_H
#define GR_COMMON_H
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

enum {
  GR_OK = 0,
  GR_EARG,   /* bad argument: the message names the parameter and its value */
  GR_EMEM,   /* out of memory, or a request too large to allocate */
  GR_EIO,    /* file system error: the message names the path */
  GR_EPARSE, /* malformed input file: the message names path:line[:col] */
  GR_ENUM,   /* NaN or infinity where a finite number is needed */
  GR_EGEOM   /* degenerate or invalid geometry */
};

typedef struct gr_err {
  int code;       /* GR_OK when nothing went wrong */
  char msg[512];  /* one line, no trailing newline */
} gr_err;

/* Fill e (may be NULL) and return code. */
int gr_fail(gr_err *e, int code, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
/* Prefix e's message with "what: " (unless it starts with what already);
 * returns e's code. */
int gr_err_prefix(gr_err *e, const char *what);
static inline void gr_err_clear(gr_err *e) { if (e) { e->code = GR_OK; e->msg[0] = 0; } }

/* Length of (dx, dy): sqrt without hypot's overflow care (coordinates are
 * millimetres, far from overflow), several times faster in hot loops. */
static inline double gr_len2d(double dx, double dy) { return sqrt(dx * dx + dy * dy); }
/* Distance between the points a and b (3 coordinates each). */
static inline double gr_dist3(const double a[3], const double b[3]) {
  return sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}
/* min / max of numbers known not to be NaN, inlined (libm's fmin / fmax
 * are calls, and show in hot loops such as a tree build). */
static inline double gr_lo(double a, double b) { return b < a ? b : a; }
static inline double gr_hi(double a, double b) { return b > a ? b : a; }
/* Where the edge (ax, ay)-(bx, by) crosses the line at height y, by the
 * half-open rule of the even-odd test (an end at y counts as above): 1 with
 * *x set, else 0. */
static inline int gr_edge_at_y(double ax, double ay, double bx, double by, double y, double *x) {
  if ((ay > y) == (by > y)) return 0;
  *x = ax + (y - ay) * (bx - ax) / (by - ay);
  return 1;
}

/* Make *p hold at least `need` elements of `elsize` bytes; *cap is updated.
 * Returns GR_OK or GR_EMEM (then *p is unchanged). */
int gr_grow(void *pp, size_t *cap, size_t need, size_t elsize);

/* A growable list of number triples (p[3 k], p[3 k + 1], p[3 k + 2]). */
typedef struct gr_trip {
  double *p;
  size_t n, cap;
} gr_trip;
/* Append (a, b, c): GR_OK or GR_EMEM (t unchanged). */
int gr_trip_push(gr_trip *t, double a, double b, double c);

/* Atomic output: write into a temporary file beside `path`, then rename it
 * into place, so a reader never sees a half-written file and a failure leaves
 * nothing behind. */
typedef struct gr_atomic {
  FILE *fp;         /* write here */
  char path[4096];  /* final path */
  char tmp[4096];   /* temporary path */
} gr_atomic;
/* Refuses (GR_EIO, naming what it is) a path that exists and is not a
 * regular file: a device, FIFO, socket, directory or symbolic link is never
 * replaced by the rename. */
int gr_atomic_open(gr_atomic *a, const char *path, gr_err *e);
/* Why `path` may not be replaced by an output: "a symbolic link", "a FIFO",
 * "a character device", ... or NULL when it is absent or a regular file. */
const char *gr_output_refusal(const char *path);
/* Flush, fsync-free close and rename. On any write error (e.g. disk full)
 * the temporary is removed and GR_EIO returned. */
int gr_atomic_commit(gr_atomic *a, gr_err *e);
void gr_atomic_abort(gr_atomic *a); /* remove the temporary; safe to call twice */

/* Wall-clock seconds (monotonic). */
double gr_now(void);

#endif
