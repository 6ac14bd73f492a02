/* common.c: see common.h. */
#include "common.h"
#include <errno.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

int gr_fail(gr_err *e, int code, const char *fmt, ...) {
  if (e) {
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(e->msg, sizeof e->msg, fmt, ap);
    va_end(ap);
    e->code = code;
  }
  return code;
}

int gr_grow(void *pp, size_t *cap, size_t need, size_t elsize) {
  void **p = (void **)pp;
  if (need <= *cap) return GR_OK;
  size_t nc = *cap ? *cap : 16;
  while (nc < need) {
    if (nc > SIZE_MAX / 2 / elsize) return GR_EMEM;
    nc *= 2;
  }
  void *np = realloc(*p, nc * elsize);
  if (!np) return GR_EMEM;
  *p = np;
  *cap = nc;
  return GR_OK;
}

int gr_trip_push(gr_trip *t, double a, double b, double c) {
  if (gr_grow(&t->p, &t->cap, t->n + 1, 3 * sizeof *t->p)) return GR_EMEM;
  t->p[3 * t->n] = a;
  t->p[3 * t->n + 1] = b;
  t->p[3 * t->n + 2] = c;
  t->n++;
  return GR_OK;
}

const char *gr_output_refusal(const char *path) {
  struct stat st;
  if (lstat(path, &st) != 0) return NULL; /* absent (or unreachable: the open says why) */
  if (S_ISREG(st.st_mode)) return NULL;
  return S_ISLNK(st.st_mode) ? "a symbolic link" : S_ISDIR(st.st_mode) ? "a directory"
       : S_ISFIFO(st.st_mode) ? "a FIFO" : S_ISCHR(st.st_mode) ? "a character device"
       : S_ISBLK(st.st_mode) ? "a block device" : S_ISSOCK(st.st_mode) ? "a socket" : "not a regular file";
}

int gr_atomic_open(gr_atomic *a, const char *path, gr_err *e) {
  memset(a, 0, sizeof *a);
  if (!path || !*path) return gr_fail(e, GR_EARG, "output path is empty");
  if (strlen(path) + 32 >= sizeof a->path)
    return gr_fail(e, GR_EARG, "output path too long: %s", path);
  strcpy(a->path, path);
  const char *what = gr_output_refusal(path);
  if (what) return gr_fail(e, GR_EIO, "cannot write %s: it is %s (only regular files are replaced)", path, what);
  snprintf(a->tmp, sizeof a->tmp, "%s.tmp%ld", path, (long)getpid());
  a->fp = fopen(a->tmp, "wb");
  if (!a->fp) {
    a->tmp[0] = 0;
    return gr_fail(e, GR_EIO, "cannot write %s: %s", path, strerror(errno));
  }
  return GR_OK;
}

int gr_atomic_commit(gr_atomic *a, gr_err *e) {
  if (!a->fp) return gr_fail(e, GR_EIO, "cannot write %s: not open", a->path);
  int bad = ferror(a->fp);
  int err = bad ? EIO : 0;
  if (fflush(a->fp) != 0) { bad = 1; err = errno; }
  if (fclose(a->fp) != 0 && !bad) { bad = 1; err = errno; }
  a->fp = NULL;
  if (!bad && rename(a->tmp, a->path) != 0) { bad = 1; err = errno; }
  if (bad) {
    remove(a->tmp);
    a->tmp[0] = 0;
    return gr_fail(e, GR_EIO, "cannot write %s: %s", a->path, strerror(err));
  }
  a->tmp[0] = 0;
  return GR_OK;
}

void gr_atomic_abort(gr_atomic *a) {
  if (a->fp) fclose(a->fp);
  a->fp = NULL;
  if (a->tmp[0]) remove(a->tmp);
  a->tmp[0] = 0;
}

double gr_now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

int gr_err_prefix(gr_err *e, const char *what) {
  if (!e) return GR_ENUM;
  size_t n = strlen(what);
  if (strncmp(e->msg, what, n) != 0) {
    char m[sizeof e->msg];
    memcpy(m, e->msg, sizeof m);
    int keep = (int)(sizeof e->msg) - (int)n - 3;
    snprintf(e->msg, sizeof e->msg, "%s: %.*s", what, keep > 0 ? keep : 0, m);
  }
  return e->code ? e->code : GR_ENUM;
}
