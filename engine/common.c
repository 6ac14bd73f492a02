/* common.c: see common.h. */
#include "common.h"
#include <errno.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
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

int gr_atomic_open(gr_atomic *a, const char *path, gr_err *e) {
  memset(a, 0, sizeof *a);
  if (!path || !*path) return gr_fail(e, GR_EARG, "output path is empty");
  if (strlen(path) + 32 >= sizeof a->path)
    return gr_fail(e, GR_EARG, "output path too long: %s", path);
  strcpy(a->path, path);
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
