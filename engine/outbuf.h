/* outbuf.h: buffered, atomic output of a large file (the CLI and OVF
 * writers). Bytes gather in an aligned buffer; whole 4 KiB blocks go to the
 * file through a second descriptor opened with O_DIRECT where the file
 * system allows it (straight to the disk, not copied into the page cache: on
 * the development machine 2.3 GB/s instead of 0.4-1.4 GB/s, and a
 * gigabyte-scale file no longer floods the cache); the last partial block is
 * written after clearing O_DIRECT. Without O_DIRECT (tmpfs, some network file
 * systems) the same code writes through the page cache. The file appears at
 * its path only at gr_outbuf_close(o, 1) (gr_atomic). */
#ifndef GR_OUTBUF_H
#define GR_OUTBUF_H
#include "common.h"

typedef struct gr_outbuf {
  gr_atomic a;
  int fd;          /* writes go here (O_DIRECT when `direct`) */
  int direct;
  char *buf;       /* GR_OUTBUF_ALIGN-aligned */
  size_t n, cap;   /* bytes pending, capacity */
  long long flushed; /* bytes written to the file: buf[j] goes to offset flushed + j */
} gr_outbuf;
#define GR_OUTBUF_ALIGN 4096

/* buffered != 0: through the page cache only. cap: initial buffer bytes. */
int gr_outbuf_open(gr_outbuf *o, const char *path, int buffered, size_t cap, gr_err *e);
/* Room for k more bytes at o->buf + o->n (may write out whole blocks first). */
int gr_outbuf_reserve(gr_outbuf *o, size_t k, gr_err *e);
int gr_outbuf_put(gr_outbuf *o, const void *p, size_t k, gr_err *e);
/* Write out everything pending (direct I/O ends here). */
int gr_outbuf_flush(gr_outbuf *o, gr_err *e);
/* Overwrite k bytes at offset off of what was flushed. */
int gr_outbuf_pwrite(gr_outbuf *o, const void *p, size_t k, long long off, gr_err *e);
/* commit != 0: flush and rename into place; 0: remove the temporary. */
int gr_outbuf_close(gr_outbuf *o, int commit, gr_err *e);

#endif
