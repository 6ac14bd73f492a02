/* kbbuf.h: little-endian byte writer and bounded reader, shared by the
 * knowledge base's record codec (kbrec.c) and index (kbindex.c). Internal. */
#ifndef GR_KBBUF_H
#define GR_KBBUF_H
#include <stdint.h>
#include <string.h>
#include "common.h"

typedef struct wbuf {
  unsigned char *p;
  size_t n, cap;
  int fail; /* set once an allocation failed; later writes are ignored */
} wbuf;

static inline void w_bytes(wbuf *w, const void *d, size_t n) {
  if (w->fail) return;
  if (n > SIZE_MAX - w->n || gr_grow(&w->p, &w->cap, w->n + n, 1)) { w->fail = 1; return; }
  if (n) memcpy(w->p + w->n, d, n);
  w->n += n;
}
static inline void w_uint(wbuf *w, uint64_t v, int nbytes) {
  unsigned char b[8];
  for (int i = 0; i < nbytes; i++) b[i] = (unsigned char)(v >> (8 * i));
  w_bytes(w, b, (size_t)nbytes);
}
static inline void w_u32(wbuf *w, uint32_t v) { w_uint(w, v, 4); }
static inline void w_u64(wbuf *w, uint64_t v) { w_uint(w, v, 8); }
static inline void w_i32(wbuf *w, int v) { w_uint(w, (uint32_t)(int32_t)v, 4); }
static inline void w_f64(wbuf *w, double d) {
  uint64_t v;
  memcpy(&v, &d, 8);
  w_u64(w, v);
}

typedef struct rbuf {
  const unsigned char *p;
  size_t n, at;
} rbuf;
static inline size_t r_left(const rbuf *r) { return r->n - r->at; }
static inline int r_uint(rbuf *r, uint64_t *v, int nbytes) {
  if (r_left(r) < (size_t)nbytes) return -1;
  uint64_t x = 0;
  for (int i = 0; i < nbytes; i++) x |= (uint64_t)r->p[r->at + i] << (8 * i);
  r->at += (size_t)nbytes;
  *v = x;
  return 0;
}
static inline int r_u32(rbuf *r, uint32_t *v) {
  uint64_t x;
  if (r_uint(r, &x, 4)) return -1;
  *v = (uint32_t)x;
  return 0;
}
static inline int r_i32(rbuf *r, int *v) {
  uint32_t x;
  if (r_u32(r, &x)) return -1;
  *v = (int)(int32_t)x;
  return 0;
}
static inline int r_u64(rbuf *r, uint64_t *v) { return r_uint(r, v, 8); }
static inline int r_f64(rbuf *r, double *d) {
  uint64_t x;
  if (r_u64(r, &x)) return -1;
  memcpy(d, &x, 8);
  return 0;
}

#endif
