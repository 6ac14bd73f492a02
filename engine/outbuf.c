/* outbuf.c: buffered, atomic output with direct I/O, see outbuf.h (moved
 * here from the CLI writer so that the OVF writer shares it). */
#define _GNU_SOURCE /* O_DIRECT */
#include "outbuf.h"
#include <errno.h>
#include <fcntl.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

int gr_outbuf_open(gr_outbuf *o, const char *path, int buffered, size_t cap, gr_err *e) {
  memset(o, 0, sizeof *o);
  o->fd = -1;
  o->cap = (cap + GR_OUTBUF_ALIGN - 1) / GR_OUTBUF_ALIGN * GR_OUTBUF_ALIGN;
  void *buf = NULL;
  if (posix_memalign(&buf, GR_OUTBUF_ALIGN, o->cap)) return gr_fail(e, GR_EMEM, "out of memory");
  o->buf = buf;
  if (gr_atomic_open(&o->a, path, e)) { free(o->buf); o->buf = NULL; return e ? e->code : GR_EIO; }
  o->fd = buffered ? -1 : open(o->a.tmp, O_WRONLY | O_DIRECT);
  o->direct = o->fd >= 0;
  if (o->fd < 0) o->fd = fileno(o->a.fp); /* no direct I/O here: the stream's descriptor, unbuffered use */
  return GR_OK;
}

static int write_all(gr_outbuf *o, const char *p, size_t k, gr_err *e) {
  while (k > 0) {
    ssize_t r = write(o->fd, p, k);
    if (r < 0 && errno == EINTR) continue;
    if (r < 0 && errno == EINVAL && o->direct) { /* the file system refuses direct I/O after all */
      o->direct = 0;
      fcntl(o->fd, F_SETFL, fcntl(o->fd, F_GETFL) & ~O_DIRECT);
      continue;
    }
    if (r <= 0) return gr_fail(e, GR_EIO, "cannot write %s: %s", o->a.path, strerror(r < 0 ? errno : ENOSPC));
    p += r;
    k -= (size_t)r;
  }
  return GR_OK;
}

/* Write the buffer out; with `all` == 0 and direct I/O only whole blocks go,
 * the rest (< GR_OUTBUF_ALIGN bytes) moves to the buffer's start. */
static int flush_some(gr_outbuf *o, int all, gr_err *e) {
  size_t k = o->n;
  if (o->direct) {
    if (all) {
      fcntl(o->fd, F_SETFL, fcntl(o->fd, F_GETFL) & ~O_DIRECT);
      o->direct = 0;
    } else {
      k -= k % GR_OUTBUF_ALIGN;
    }
  }
  if (write_all(o, o->buf, k, e)) return e->code;
  o->flushed += (long long)k;
  memmove(o->buf, o->buf + k, o->n - k);
  o->n -= k;
  return GR_OK;
}

int gr_outbuf_reserve(gr_outbuf *o, size_t k, gr_err *e) {
  if (o->n + k <= o->cap) return GR_OK;
  if (flush_some(o, 0, e)) return e->code;
  if (o->n + k > o->cap) {
    size_t cap = (o->n + k + GR_OUTBUF_ALIGN - 1) / GR_OUTBUF_ALIGN * GR_OUTBUF_ALIGN;
    void *nb = NULL;
    if (posix_memalign(&nb, GR_OUTBUF_ALIGN, cap)) return gr_fail(e, GR_EMEM, "out of memory");
    memcpy(nb, o->buf, o->n);
    free(o->buf);
    o->buf = nb;
    o->cap = cap;
  }
  return GR_OK;
}

int gr_outbuf_put(gr_outbuf *o, const void *p, size_t k, gr_err *e) {
  if (gr_outbuf_reserve(o, k, e)) return e->code;
  memcpy(o->buf + o->n, p, k);
  o->n += k;
  return GR_OK;
}

int gr_outbuf_flush(gr_outbuf *o, gr_err *e) { return flush_some(o, 1, e); }

int gr_outbuf_pwrite(gr_outbuf *o, const void *p, size_t k, long long off, gr_err *e) {
  if (pwrite(o->fd, p, k, (off_t)off) != (ssize_t)k)
    return gr_fail(e, GR_EIO, "cannot write %s: %s", o->a.path, strerror(errno));
  return GR_OK;
}

int gr_outbuf_close(gr_outbuf *o, int commit, gr_err *e) {
  int rc = commit ? flush_some(o, 1, e) : GR_OK;
  if (o->fd >= 0 && o->a.fp && o->fd != fileno(o->a.fp) && close(o->fd) && !rc && commit)
    rc = gr_fail(e, GR_EIO, "cannot write %s: %s", o->a.path, strerror(errno));
  o->fd = -1;
  if (commit && !rc) rc = gr_atomic_commit(&o->a, e);
  else gr_atomic_abort(&o->a);
  free(o->buf);
  o->buf = NULL;
  return rc;
}
