/* kb.c: the knowledge base of toolpath templates, see kb.h and doc/kb.md. */
#include "kb.h"
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

/* ================================================================ SHA-256 */
/* The digest comes from nettle (Debian's nettle-dev, libnettle): the same
 * FIPS 180-4 SHA-256 as before, so every stored key and checksum verifies. */
void gr_sha256_init(gr_sha256 *s) { sha256_init(&s->ctx); }

void gr_sha256_update(gr_sha256 *s, const void *data, size_t n) { sha256_update(&s->ctx, n, data); }

void gr_sha256_final(gr_sha256 *s, unsigned char out[32]) { sha256_digest(&s->ctx, SHA256_DIGEST_SIZE, out); }

static void hex32(const unsigned char d[32], char out[65]) {
  static const char hx[] = "0123456789abcdef";
  for (int i = 0; i < 32; i++) {
    out[2 * i] = hx[d[i] >> 4];
    out[2 * i + 1] = hx[d[i] & 15];
  }
  out[64] = 0;
}

void gr_sha256_hex(const void *data, size_t n, char out[65]) {
  gr_sha256 s;
  unsigned char d[32];
  gr_sha256_init(&s);
  gr_sha256_update(&s, data, n);
  gr_sha256_final(&s, d);
  hex32(d, out);
}

static int valid_key(const char *k) {
  if (!k) return 0;
  for (int i = 0; i < 64; i++)
    if (!((k[i] >= '0' && k[i] <= '9') || (k[i] >= 'a' && k[i] <= 'f'))) return 0;
  return k[64] == 0;
}

/* ============================================================== templates */
gr_template *gr_template_new(const char *signature, int nlayers, int nslots,
                             int with_extra, gr_err *e) {
  if (!signature) { gr_fail(e, GR_EARG, "template signature is NULL"); return NULL; }
  if (nlayers < 0 || nlayers > 10000000) {
    gr_fail(e, GR_EARG, "template nlayers must be in [0, 1e7], got %d", nlayers);
    return NULL;
  }
  if (nslots < 1 || nslots > 1024) {
    gr_fail(e, GR_EARG, "template nslots must be in [1, 1024], got %d", nslots);
    return NULL;
  }
  gr_template *t = calloc(1, sizeof *t);
  if (!t) goto oom;
  for (int i = 0; i < GR_TEMPLATE_NQ; i++) t->quality[i] = NAN;
  t->nlayers = nlayers;
  t->nslots = nslots;
  size_t nl = (size_t)nlayers, nr = nl * (size_t)nslots;
  t->signature = strdup(signature);
  t->z = calloc(nl ? nl : 1, sizeof *t->z);
  t->rings = calloc(nr ? nr : 1, sizeof *t->rings);
  if (!t->signature || !t->z || !t->rings) goto oom;
  for (size_t i = 0; i < nr; i++)
    if (!(t->rings[i] = gr_rings_new())) goto oom;
  if (with_extra) {
    t->extra = calloc(nl ? nl : 1, sizeof *t->extra);
    if (!t->extra) goto oom;
    for (size_t i = 0; i < nl; i++)
      if (!(t->extra[i] = gr_layer_new(0))) goto oom;
  }
  gr_sha256_hex(signature, strlen(signature), t->key);
  return t;
oom:
  gr_template_free(t);
  gr_fail(e, GR_EMEM, "out of memory creating a template of %d layers x %d slots",
          nlayers, nslots);
  return NULL;
}

void gr_template_free(gr_template *t) {
  if (!t) return;
  size_t nl = t->nlayers > 0 ? (size_t)t->nlayers : 0;
  size_t nr = nl * (size_t)(t->nslots > 0 ? t->nslots : 0);
  if (t->rings)
    for (size_t i = 0; i < nr; i++) gr_rings_free(t->rings[i]);
  if (t->extra)
    for (size_t i = 0; i < nl; i++) gr_layer_free(t->extra[i]);
  free(t->rings);
  free(t->extra);
  free(t->z);
  free(t->signature);
  free(t->meta);
  free(t);
}

int gr_template_set_meta(gr_template *t, const char *meta, gr_err *e) {
  char *m = NULL;
  if (meta && !(m = strdup(meta)))
    return gr_fail(e, GR_EMEM, "out of memory copying template meta");
  free(t->meta);
  t->meta = m;
  return GR_OK;
}

/* ---- little-endian byte writer and bounded reader ---- */
typedef struct wbuf {
  unsigned char *p;
  size_t n, cap;
  int fail; /* set once an allocation failed; later writes are ignored */
} wbuf;

static void w_bytes(wbuf *w, const void *d, size_t n) {
  if (w->fail) return;
  if (n > SIZE_MAX - w->n || gr_grow(&w->p, &w->cap, w->n + n, 1)) { w->fail = 1; return; }
  if (n) memcpy(w->p + w->n, d, n);
  w->n += n;
}
static void w_uint(wbuf *w, uint64_t v, int nbytes) {
  unsigned char b[8];
  for (int i = 0; i < nbytes; i++) b[i] = (unsigned char)(v >> (8 * i));
  w_bytes(w, b, (size_t)nbytes);
}
static void w_u32(wbuf *w, uint32_t v) { w_uint(w, v, 4); }
static void w_u64(wbuf *w, uint64_t v) { w_uint(w, v, 8); }
static void w_i32(wbuf *w, int v) { w_uint(w, (uint32_t)(int32_t)v, 4); }
static void w_f64(wbuf *w, double d) {
  uint64_t v;
  memcpy(&v, &d, 8);
  w_u64(w, v);
}

typedef struct rbuf {
  const unsigned char *p;
  size_t n, at;
} rbuf;
static size_t r_left(const rbuf *r) { return r->n - r->at; }
static int r_uint(rbuf *r, uint64_t *v, int nbytes) {
  if (r_left(r) < (size_t)nbytes) return -1;
  uint64_t x = 0;
  for (int i = 0; i < nbytes; i++) x |= (uint64_t)r->p[r->at + i] << (8 * i);
  r->at += (size_t)nbytes;
  *v = x;
  return 0;
}
static int r_u32(rbuf *r, uint32_t *v) {
  uint64_t x;
  if (r_uint(r, &x, 4)) return -1;
  *v = (uint32_t)x;
  return 0;
}
static int r_i32(rbuf *r, int *v) {
  uint32_t x;
  if (r_u32(r, &x)) return -1;
  *v = (int)(int32_t)x;
  return 0;
}
static int r_u64(rbuf *r, uint64_t *v) { return r_uint(r, v, 8); }
static int r_f64(rbuf *r, double *d) {
  uint64_t x;
  if (r_u64(r, &x)) return -1;
  memcpy(d, &x, 8);
  return 0;
}

/* ---- blob header ---- */
#define GTP_MAGIC "GRADUSTP"
#define GTP_VERSION 1u
#define GTP_HEADER 56u /* magic 8 + version 4 + header size 4 + payload length 8 + sha 32 */
#define GTP_MAX_PAYLOAD ((uint64_t)1 << 34) /* 16 GiB: anything larger is garbage */

static void encode_rings(wbuf *w, const gr_rings *r) {
  size_t nr = r ? r->nrings : 0, np = r ? r->npts : 0;
  int hp = r && r->parent && nr > 0;
  w_u64(w, nr);
  w_u64(w, np);
  w_u32(w, (uint32_t)hp);
  for (size_t i = 0; i < nr; i++) w_u64(w, gr_ring_len(r, i));
  for (size_t i = 0; i < 2 * np; i++) w_f64(w, r->xy[i]);
  if (hp)
    for (size_t i = 0; i < nr; i++) w_i32(w, r->parent[i]);
}

static void encode_layer(wbuf *w, const gr_layer *l) {
  w_f64(w, l->z);
  w_i32(w, l->thin_walls);
  w_f64(w, l->area);
  w_u64(w, l->npts);
  w_u64(w, l->nb);
  for (size_t i = 0; i < l->nb; i++) {
    const gr_block *b = &l->b[i];
    w_i32(w, b->shape);
    w_i32(w, b->kind);
    w_i32(w, b->laser);
    w_i32(w, b->dir);
    w_u64(w, b->start);
    w_u64(w, b->n);
  }
  for (size_t i = 0; i < 2 * l->npts; i++) w_f64(w, l->xy[i]);
}

/* Encode with an explicit creation time (gr_kb_put stamps unset ones). */
static int encode_blob(const gr_template *t, long long created, unsigned char **buf,
                       size_t *n, gr_err *e) {
  *buf = NULL;
  *n = 0;
  if (!t) return gr_fail(e, GR_EARG, "template is NULL");
  if (!t->signature) return gr_fail(e, GR_EARG, "template signature is NULL");
  if (t->nlayers < 0) return gr_fail(e, GR_EARG, "template nlayers must be >= 0, got %d", t->nlayers);
  if (t->nslots < 1) return gr_fail(e, GR_EARG, "template nslots must be >= 1, got %d", t->nslots);
  if (t->nlayers > 0 && (!t->z || !t->rings))
    return gr_fail(e, GR_EARG, "template of %d layers has no z or rings array", t->nlayers);
  if (t->qualified != 0 && t->qualified != 1)
    return gr_fail(e, GR_EARG, "template qualified must be 0 or 1, got %d", t->qualified);
  size_t siglen = strlen(t->signature), metalen = t->meta ? strlen(t->meta) : 0;
  if (siglen > UINT32_MAX || metalen > UINT32_MAX)
    return gr_fail(e, GR_EARG, "template signature or meta longer than 4 GiB");
  char key[65];
  gr_sha256_hex(t->signature, siglen, key);
  if (strcmp(key, t->key) != 0)
    return gr_fail(e, GR_EARG, "template key '%.64s' is not the SHA-256 of its signature (%s)",
                   t->key, key);
  if (t->extra)
    for (int i = 0; i < t->nlayers; i++)
      if (!t->extra[i]) return gr_fail(e, GR_EARG, "template extra layer %d is NULL", i);

  wbuf w = {0};
  unsigned char zero[GTP_HEADER] = {0};
  w_bytes(&w, zero, GTP_HEADER); /* header filled in below */
  w_u32(&w, (uint32_t)t->nlayers);
  w_u32(&w, (uint32_t)t->nslots);
  w_u32(&w, t->extra ? 1u : 0u);
  w_i32(&w, t->qualified);
  w_u64(&w, (uint64_t)created);
  for (int i = 0; i < GR_TEMPLATE_NQ; i++) w_f64(&w, t->quality[i]);
  w_bytes(&w, key, 64);
  w_u32(&w, (uint32_t)siglen);
  w_bytes(&w, t->signature, siglen);
  w_u32(&w, (uint32_t)metalen);
  w_bytes(&w, t->meta, metalen);
  for (int i = 0; i < t->nlayers; i++) w_f64(&w, t->z[i]);
  size_t nr = (size_t)t->nlayers * (size_t)t->nslots;
  for (size_t i = 0; i < nr; i++) encode_rings(&w, t->rings[i]);
  if (t->extra)
    for (int i = 0; i < t->nlayers; i++) encode_layer(&w, t->extra[i]);
  if (w.fail) {
    free(w.p);
    return gr_fail(e, GR_EMEM, "out of memory encoding template %.16s", key);
  }
  uint64_t plen = w.n - GTP_HEADER;
  unsigned char d[32];
  gr_sha256 s;
  gr_sha256_init(&s);
  gr_sha256_update(&s, w.p + GTP_HEADER, (size_t)plen);
  gr_sha256_final(&s, d);
  memcpy(w.p, GTP_MAGIC, 8);
  for (int i = 0; i < 4; i++) w.p[8 + i] = (unsigned char)(GTP_VERSION >> (8 * i));
  for (int i = 0; i < 4; i++) w.p[12 + i] = (unsigned char)(GTP_HEADER >> (8 * i));
  for (int i = 0; i < 8; i++) w.p[16 + i] = (unsigned char)(plen >> (8 * i));
  memcpy(w.p + 24, d, 32);
  *buf = w.p;
  *n = w.n;
  return GR_OK;
}

int gr_template_encode(const gr_template *t, unsigned char **buf, size_t *n, gr_err *e) {
  return encode_blob(t, t ? t->created : 0, buf, n, e);
}

#define TRUNC(what) gr_fail(e, GR_EPARSE, "truncated payload reading %s at byte %zu", what, r->at + GTP_HEADER)

/* Read one ring set, checking every count against the bytes left before
 * allocating, so that garbage cannot ask for huge allocations. */
static int decode_rings(rbuf *r, gr_rings *g, gr_err *e) {
  uint64_t nr, np;
  uint32_t hp;
  if (r_u64(r, &nr) || r_u64(r, &np) || r_u32(r, &hp)) return TRUNC("a ring set header");
  if (hp > 1) return gr_fail(e, GR_EPARSE, "ring set parent flag is %u, expected 0 or 1", hp);
  if (nr > r_left(r) / 8 || np > r_left(r) / 16 || (hp && nr > r_left(r) / 4))
    return gr_fail(e, GR_EPARSE, "ring set claims %llu rings and %llu points, more than the %zu bytes left",
                   (unsigned long long)nr, (unsigned long long)np, r_left(r));
  if (gr_grow(&g->start, &g->caprings, (size_t)nr + 1, sizeof *g->start) ||
      gr_grow(&g->xy, &g->cappts, (size_t)np, 2 * sizeof(double)))
    return gr_fail(e, GR_EMEM, "out of memory decoding %llu rings", (unsigned long long)nr);
  uint64_t sum = 0;
  g->start[0] = 0;
  for (size_t i = 0; i < nr; i++) {
    uint64_t len;
    if (r_u64(r, &len)) return TRUNC("ring lengths");
    if (len == 0 || len > np - sum)
      return gr_fail(e, GR_EPARSE, "ring %zu has length %llu (points %llu of %llu used)", i,
                     (unsigned long long)len, (unsigned long long)sum, (unsigned long long)np);
    sum += len;
    g->start[i + 1] = (size_t)sum;
  }
  if (sum != np)
    return gr_fail(e, GR_EPARSE, "ring lengths sum to %llu, expected %llu points",
                   (unsigned long long)sum, (unsigned long long)np);
  for (size_t i = 0; i < 2 * np; i++)
    if (r_f64(r, &g->xy[i])) return TRUNC("ring points");
  g->nrings = (size_t)nr;
  g->npts = (size_t)np;
  if (hp) {
    g->parent = malloc((size_t)nr * sizeof *g->parent);
    if (!g->parent) return gr_fail(e, GR_EMEM, "out of memory decoding ring parents");
    for (size_t i = 0; i < nr; i++) {
      if (r_i32(r, &g->parent[i])) return TRUNC("ring parents");
      if (g->parent[i] < -1 || (g->parent[i] >= 0 && (uint64_t)g->parent[i] >= nr))
        return gr_fail(e, GR_EPARSE, "ring %zu has parent %d, out of range", i, g->parent[i]);
    }
  }
  return GR_OK;
}

static int decode_layer(rbuf *r, gr_layer *l, gr_err *e) {
  uint64_t np, nb;
  if (r_f64(r, &l->z) || r_i32(r, &l->thin_walls) || r_f64(r, &l->area) || r_u64(r, &np) ||
      r_u64(r, &nb))
    return TRUNC("an extra layer header");
  if (nb > r_left(r) / 32 || np > r_left(r) / 16)
    return gr_fail(e, GR_EPARSE, "extra layer claims %llu blocks and %llu points, more than the %zu bytes left",
                   (unsigned long long)nb, (unsigned long long)np, r_left(r));
  if (gr_grow(&l->b, &l->capb, (size_t)nb, sizeof *l->b) ||
      gr_grow(&l->xy, &l->cappts, (size_t)np, 2 * sizeof(double)))
    return gr_fail(e, GR_EMEM, "out of memory decoding %llu blocks", (unsigned long long)nb);
  for (size_t i = 0; i < nb; i++) {
    gr_block *b = &l->b[i];
    uint64_t st, n;
    if (r_i32(r, &b->shape) || r_i32(r, &b->kind) || r_i32(r, &b->laser) || r_i32(r, &b->dir) ||
        r_u64(r, &st) || r_u64(r, &n))
      return TRUNC("blocks");
    if (b->shape < 0 || b->shape > GR_SEGMENTS || b->kind < 0 || b->kind >= GR_NKINDS)
      return gr_fail(e, GR_EPARSE, "block %zu has shape %d kind %d, out of range", i, b->shape, b->kind);
    if (n > np || st > np - n)
      return gr_fail(e, GR_EPARSE, "block %zu spans points [%llu, +%llu) beyond %llu", i,
                     (unsigned long long)st, (unsigned long long)n, (unsigned long long)np);
    b->start = (size_t)st;
    b->n = (size_t)n;
  }
  l->nb = (size_t)nb;
  for (size_t i = 0; i < 2 * np; i++)
    if (r_f64(r, &l->xy[i])) return TRUNC("extra layer points");
  l->npts = (size_t)np;
  return GR_OK;
}

/* Read a length-prefixed string into a new NUL-terminated copy. */
static int decode_str(rbuf *r, char **out, const char *what, gr_err *e) {
  uint32_t len;
  if (r_u32(r, &len)) return TRUNC(what);
  if (len > r_left(r))
    return gr_fail(e, GR_EPARSE, "%s length %u exceeds the %zu bytes left", what, len, r_left(r));
  if (memchr(r->p + r->at, 0, len)) return gr_fail(e, GR_EPARSE, "%s contains a NUL byte", what);
  char *s = malloc((size_t)len + 1);
  if (!s) return gr_fail(e, GR_EMEM, "out of memory decoding %s", what);
  memcpy(s, r->p + r->at, len);
  s[len] = 0;
  r->at += len;
  *out = s;
  return GR_OK;
}

static int decode_payload(rbuf *r, gr_template **out, gr_err *e) {
  uint32_t nl, ns, flags;
  int qual;
  uint64_t created;
  double q[GR_TEMPLATE_NQ];
  char key[65];
  if (r_u32(r, &nl) || r_u32(r, &ns) || r_u32(r, &flags) || r_i32(r, &qual) || r_u64(r, &created))
    return TRUNC("the template header");
  for (int i = 0; i < GR_TEMPLATE_NQ; i++)
    if (r_f64(r, &q[i])) return TRUNC("quality");
  if (r_left(r) < 64) return TRUNC("the key");
  memcpy(key, r->p + r->at, 64);
  key[64] = 0;
  r->at += 64;
  if (!valid_key(key)) return gr_fail(e, GR_EPARSE, "stored key is not 64 lowercase hex digits");
  if (flags > 1) return gr_fail(e, GR_EPARSE, "flags are 0x%x, only bit 0 is defined", flags);
  if (qual != 0 && qual != 1) return gr_fail(e, GR_EPARSE, "qualified is %d, expected 0 or 1", qual);
  if (ns < 1 || ns > 1024) return gr_fail(e, GR_EPARSE, "nslots is %u, expected 1..1024", ns);
  /* every layer costs >= 8 bytes of z and >= 20 bytes per ring set */
  if (nl > 10000000 || (uint64_t)nl * (8 + 20 * (uint64_t)ns) > r_left(r))
    return gr_fail(e, GR_EPARSE, "nlayers %u x nslots %u does not fit in the %zu bytes left", nl, ns, r_left(r));
  char *sig = NULL, *meta = NULL;
  int rc = decode_str(r, &sig, "signature", e);
  if (rc == GR_OK) rc = decode_str(r, &meta, "meta", e);
  if (rc != GR_OK) { free(sig); return rc; }
  char k2[65];
  gr_sha256_hex(sig, strlen(sig), k2);
  if (strcmp(k2, key) != 0) {
    free(sig); free(meta);
    return gr_fail(e, GR_EPARSE, "stored key %.12s... is not the SHA-256 of the stored signature", key);
  }
  gr_err e2;
  gr_template *t = gr_template_new(sig, (int)nl, (int)ns, (int)(flags & 1), &e2);
  free(sig);
  if (!t) { free(meta); return gr_fail(e, e2.code, "%s", e2.msg); }
  if (meta && !*meta) { free(meta); meta = NULL; }
  t->meta = meta;
  t->qualified = qual;
  t->created = (long long)created;
  memcpy(t->quality, q, sizeof q);
  rc = GR_OK;
  for (uint32_t i = 0; i < nl && rc == GR_OK; i++)
    if (r_f64(r, &t->z[i])) rc = TRUNC("z");
  size_t nr = (size_t)nl * ns;
  for (size_t i = 0; i < nr && rc == GR_OK; i++) rc = decode_rings(r, t->rings[i], e);
  if (t->extra)
    for (uint32_t i = 0; i < nl && rc == GR_OK; i++) rc = decode_layer(r, t->extra[i], e);
  if (rc == GR_OK && r_left(r) != 0)
    rc = gr_fail(e, GR_EPARSE, "%zu unexpected bytes after the template", r_left(r));
  if (rc != GR_OK) { gr_template_free(t); return rc; }
  *out = t;
  return GR_OK;
}

int gr_template_decode(const void *buf, size_t n, gr_template **out, gr_err *e) {
  const unsigned char *p = buf;
  *out = NULL;
  if (!p || n < 16) return gr_fail(e, GR_EPARSE, "file too short (%zu bytes) for a template header", n);
  if (memcmp(p, GTP_MAGIC, 8) != 0) return gr_fail(e, GR_EPARSE, "bad magic: not a Gradus template");
  uint32_t ver = 0, hsz = 0;
  for (int i = 0; i < 4; i++) ver |= (uint32_t)p[8 + i] << (8 * i);
  for (int i = 0; i < 4; i++) hsz |= (uint32_t)p[12 + i] << (8 * i);
  if (ver != GTP_VERSION)
    return gr_fail(e, GR_EPARSE, "format version %u, this build reads version %u", ver, GTP_VERSION);
  if (hsz != GTP_HEADER) return gr_fail(e, GR_EPARSE, "header size %u, expected %u", hsz, GTP_HEADER);
  if (n < GTP_HEADER) return gr_fail(e, GR_EPARSE, "file too short (%zu bytes) for a template header", n);
  uint64_t plen = 0;
  for (int i = 0; i < 8; i++) plen |= (uint64_t)p[16 + i] << (8 * i);
  if (plen != (uint64_t)(n - GTP_HEADER))
    return gr_fail(e, GR_EPARSE, "size mismatch: header says %llu payload bytes, file has %zu",
                   (unsigned long long)plen, n - GTP_HEADER);
  unsigned char d[32];
  gr_sha256 s;
  gr_sha256_init(&s);
  gr_sha256_update(&s, p + GTP_HEADER, n - GTP_HEADER);
  gr_sha256_final(&s, d);
  if (memcmp(d, p + 24, 32) != 0) return gr_fail(e, GR_EPARSE, "checksum mismatch");
  rbuf r = {p + GTP_HEADER, n - GTP_HEADER, 0};
  return decode_payload(&r, out, e);
}

/* ================================================================= files */
struct gr_kb {
  char *dir;             /* store directory, as given */
  pthread_mutex_t lock;  /* serialises writers inside one process */
};

const char *gr_kb_dir(const gr_kb *kb) { return kb->dir; }

/* "<a>/<b>" into a new string, or NULL. */
static char *join(const char *a, const char *b) {
  size_t na = strlen(a), nb = strlen(b);
  char *s = malloc(na + nb + 2);
  if (!s) return NULL;
  memcpy(s, a, na);
  s[na] = '/';
  memcpy(s + na + 1, b, nb + 1);
  return s;
}

static int mkdir_p(const char *path, gr_err *e) {
  char *p = strdup(path);
  if (!p) return gr_fail(e, GR_EMEM, "out of memory");
  for (char *c = p + 1;; c++) {
    if (*c == '/' || *c == 0) {
      char save = *c;
      *c = 0;
      if (mkdir(p, 0755) != 0 && errno != EEXIST) {
        int err = errno;
        gr_fail(e, GR_EIO, "cannot create directory %s: %s", p, strerror(err));
        free(p);
        return GR_EIO;
      }
      *c = save;
      if (!save) break;
    }
  }
  struct stat st;
  int ok = stat(p, &st) == 0 && S_ISDIR(st.st_mode);
  free(p);
  if (!ok) return gr_fail(e, GR_EIO, "knowledge base path %s is not a directory", path);
  return GR_OK;
}

/* Whole file into a new buffer. Returns 0, or an errno value. */
static int read_all(const char *path, unsigned char **buf, size_t *n) {
  *buf = NULL;
  *n = 0;
  int fd = open(path, O_RDONLY | O_CLOEXEC);
  if (fd < 0) return errno;
  struct stat st;
  if (fstat(fd, &st) != 0) { int err = errno; close(fd); return err; }
  if (!S_ISREG(st.st_mode)) { close(fd); return EISDIR; }
  if ((uint64_t)st.st_size > GTP_MAX_PAYLOAD) { close(fd); return EFBIG; }
  size_t cap = (size_t)st.st_size, len = 0;
  unsigned char *p = malloc(cap + 1);
  if (!p) { close(fd); return ENOMEM; }
  for (;;) {
    if (len == cap) { /* the file grew: read on */
      if (gr_grow(&p, &cap, cap + 4096, 1)) { free(p); close(fd); return ENOMEM; }
    }
    ssize_t k = read(fd, p + len, cap - len);
    if (k < 0 && errno == EINTR) continue;
    if (k < 0) { int err = errno; free(p); close(fd); return err; }
    if (k == 0) break;
    len += (size_t)k;
  }
  close(fd);
  if (gr_grow(&p, &cap, len + 1, 1)) { free(p); return ENOMEM; } /* spare byte for a NUL */
  *buf = p;
  *n = len;
  return 0;
}

/* Write data to `path` atomically: a unique temporary "<path>.tmp-XXXXXX" in
 * the same directory, fsync, rename. On failure the temporary is removed. */
static int write_atomic(const char *path, const void *data, size_t n, gr_err *e) {
  size_t np = strlen(path);
  char *tmp = malloc(np + 12);
  if (!tmp) return gr_fail(e, GR_EMEM, "out of memory");
  memcpy(tmp, path, np);
  memcpy(tmp + np, ".tmp-XXXXXX", 12);
  int fd = mkstemp(tmp);
  if (fd < 0) {
    int err = errno;
    free(tmp);
    return gr_fail(e, GR_EIO, "cannot write %s: %s", path, strerror(err));
  }
  int err = 0;
  if (fchmod(fd, 0644) != 0) err = errno;
  const unsigned char *p = data;
  size_t done = 0;
  while (!err && done < n) {
    ssize_t k = write(fd, p + done, n - done);
    if (k < 0 && errno == EINTR) continue;
    if (k < 0) err = errno;
    else done += (size_t)k;
  }
  if (!err && fsync(fd) != 0) err = errno;
  if (close(fd) != 0 && !err) err = errno;
  if (!err && rename(tmp, path) != 0) err = errno;
  if (err) unlink(tmp);
  free(tmp);
  if (err) return gr_fail(e, GR_EIO, "cannot write %s: %s", path, strerror(err));
  return GR_OK;
}

/* Take the writer lock: the in-process mutex, then flock on <dir>/lock.
 * Returns the lock file descriptor (>= 0) or -1 with e filled. */
static int lock_take(gr_kb *kb, gr_err *e) {
  pthread_mutex_lock(&kb->lock);
  char *p = join(kb->dir, "lock");
  int fd = p ? open(p, O_RDWR | O_CREAT | O_CLOEXEC, 0644) : -1;
  int err = p ? errno : ENOMEM;
  while (fd >= 0 && flock(fd, LOCK_EX) != 0) {
    if (errno == EINTR) continue;
    err = errno;
    close(fd);
    fd = -1;
  }
  if (fd < 0) {
    gr_fail(e, GR_EIO, "cannot lock %s/lock: %s", kb->dir, strerror(err));
    pthread_mutex_unlock(&kb->lock);
  }
  free(p);
  return fd;
}

static void lock_drop(gr_kb *kb, int fd) {
  close(fd); /* releases the flock */
  pthread_mutex_unlock(&kb->lock);
}

int gr_kb_default_dir(char *out, size_t n) {
  const char *base, *suffix;
  if ((base = getenv("GRADUS_CACHE_DIR")) && *base) suffix = "/kb";
  else if ((base = getenv("XDG_CACHE_HOME")) && *base) suffix = "/gradus/kb";
  else if ((base = getenv("HOME")) && *base) suffix = "/.cache/gradus/kb";
  else return GR_EARG;
  int k = snprintf(out, n, "%s%s", base, suffix);
  return (k < 0 || (size_t)k >= n) ? GR_EARG : GR_OK;
}

gr_kb *gr_kb_open(const char *dir, gr_err *e) {
  if (!dir || !*dir) { gr_fail(e, GR_EARG, "knowledge base directory is empty"); return NULL; }
  gr_kb *kb = calloc(1, sizeof *kb);
  char *t = NULL, *lk = NULL;
  if (!kb || !(kb->dir = strdup(dir)) || !(t = join(dir, "t")) || !(lk = join(dir, "lock"))) {
    gr_fail(e, GR_EMEM, "out of memory opening %s", dir);
    goto fail;
  }
  size_t nd = strlen(kb->dir); /* "a/b/" -> "a/b" so that joined paths look clean */
  while (nd > 1 && kb->dir[nd - 1] == '/') kb->dir[--nd] = 0;
  if (mkdir_p(t, e) != GR_OK) goto fail;
  int fd = open(lk, O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) {
    gr_fail(e, GR_EIO, "cannot create %s: %s", lk, strerror(errno));
    goto fail;
  }
  close(fd);
  if (pthread_mutex_init(&kb->lock, NULL) != 0) {
    gr_fail(e, GR_EMEM, "cannot create a mutex for %s", dir);
    goto fail;
  }
  free(t);
  free(lk);
  return kb;
fail:
  free(t);
  free(lk);
  if (kb) free(kb->dir);
  free(kb);
  return NULL;
}

void gr_kb_close(gr_kb *kb) {
  if (!kb) return;
  pthread_mutex_destroy(&kb->lock);
  free(kb->dir);
  free(kb);
}

static char *blob_path(const gr_kb *kb, const char *key) {
  size_t nd = strlen(kb->dir);
  char *s = malloc(nd + 3 + 64 + 5);
  if (s) sprintf(s, "%s/t/%s.gtp", kb->dir, key);
  return s;
}

/* Read and check one blob; `key` is the name it is stored under. Returns
 * GR_OK with *out, ENOENT-absent as GR_OK with *out NULL and *absent = 1, or
 * GR_EPARSE with the reason in e. *bytes gets the file size. */
static int load_blob(const gr_kb *kb, const char *key, gr_template **out, size_t *bytes,
                     int *absent, gr_err *e) {
  *out = NULL;
  *absent = 0;
  char *path = blob_path(kb, key);
  if (!path) return gr_fail(e, GR_EMEM, "out of memory");
  unsigned char *buf;
  size_t n;
  int err = read_all(path, &buf, &n);
  free(path);
  if (err == ENOENT) { *absent = 1; return GR_OK; }
  if (err == ENOMEM) return gr_fail(e, GR_EMEM, "out of memory reading template %s", key);
  if (err) return gr_fail(e, GR_EPARSE, "cannot read: %s", strerror(err));
  if (bytes) *bytes = n;
  int rc = gr_template_decode(buf, n, out, e);
  free(buf);
  if (rc == GR_OK && strcmp((*out)->key, key) != 0) {
    char other[65];
    memcpy(other, (*out)->key, 65);
    gr_template_free(*out);
    *out = NULL;
    return gr_fail(e, GR_EPARSE, "holds template %.12s..., not the one its name says", other);
  }
  return rc;
}

int gr_kb_get(gr_kb *kb, const char *key, gr_template **out, char *warning, size_t wn,
              gr_err *e) {
  *out = NULL;
  if (warning && wn) warning[0] = 0;
  if (!valid_key(key))
    return gr_fail(e, GR_EARG, "template key must be 64 lowercase hex digits, got '%.80s'",
                   key ? key : "(null)");
  gr_err e2;
  gr_err_clear(&e2);
  int absent;
  int rc = load_blob(kb, key, out, NULL, &absent, &e2);
  if (rc == GR_EMEM) return gr_fail(e, rc, "%s", e2.msg);
  if (rc != GR_OK) {
    if (warning && wn)
      snprintf(warning, wn, "knowledge base: %s/t/%s.gtp is damaged (%s); ignored", kb->dir, key,
               e2.msg);
    *out = NULL;
  }
  return GR_OK;
}

/* ================================================================= index */
typedef struct entries {
  gr_kb_entry *v;
  size_t n, cap;
} entries;

void gr_kb_entries_free(gr_kb_entry *v, size_t n) {
  if (!v) return;
  for (size_t i = 0; i < n; i++) free(v[i].signature);
  free(v);
}

static int entry_cmp(const void *a, const void *b) {
  return strcmp(((const gr_kb_entry *)a)->key, ((const gr_kb_entry *)b)->key);
}

static gr_kb_entry *entries_find(entries *es, const char *key) {
  for (size_t i = 0; i < es->n; i++)
    if (strcmp(es->v[i].key, key) == 0) return &es->v[i];
  return NULL;
}

/* Add (or replace, by key) an entry describing t stored in `bytes` bytes. */
static int entries_set(entries *es, const gr_template *t, long long created, size_t bytes) {
  char *sig = strdup(t->signature);
  if (!sig) return GR_EMEM;
  gr_kb_entry *x = entries_find(es, t->key);
  if (!x) {
    if (gr_grow(&es->v, &es->cap, es->n + 1, sizeof *es->v)) { free(sig); return GR_EMEM; }
    x = &es->v[es->n++];
    memset(x, 0, sizeof *x);
    memcpy(x->key, t->key, 65);
  }
  free(x->signature);
  x->signature = sig;
  x->bytes = bytes;
  x->qualified = t->qualified;
  memcpy(x->quality, t->quality, sizeof x->quality);
  x->created = created;
  return GR_OK;
}

static void w_str(wbuf *w, const char *s) { w_bytes(w, s, strlen(s)); }

static void w_fmt_double(wbuf *w, double d) {
  char b[40];
  if (isnan(d)) strcpy(b, ".nan");
  else if (isinf(d)) strcpy(b, d > 0 ? ".inf" : "-.inf");
  else snprintf(b, sizeof b, "%.17g", d);
  w_str(w, b);
}

/* YAML double-quoted scalar: escapes for '"', '\\' and control bytes; UTF-8
 * passes through. */
static void w_quoted(wbuf *w, const char *s) {
  w_str(w, "\"");
  for (const unsigned char *c = (const unsigned char *)s; *c; c++) {
    char b[8];
    if (*c == '"') w_str(w, "\\\"");
    else if (*c == '\\') w_str(w, "\\\\");
    else if (*c == '\n') w_str(w, "\\n");
    else if (*c == '\t') w_str(w, "\\t");
    else if (*c == '\r') w_str(w, "\\r");
    else if (*c < 0x20 || *c == 0x7f) { snprintf(b, sizeof b, "\\x%02x", *c); w_str(w, b); }
    else w_bytes(w, c, 1);
  }
  w_str(w, "\"");
}

static void fmt_time(long long t, char out[32]) {
  time_t tt = (time_t)t;
  struct tm tm;
  if (!gmtime_r(&tt, &tm) || !strftime(out, 32, "%Y-%m-%dT%H:%M:%SZ", &tm))
    strcpy(out, "1970-01-01T00:00:00Z");
}

static int parse_time(const char *s, long long *t) {
  struct tm tm;
  memset(&tm, 0, sizeof tm);
  int n = 0;
  if (sscanf(s, "%4d-%2d-%2dT%2d:%2d:%2dZ%n", &tm.tm_year, &tm.tm_mon, &tm.tm_mday, &tm.tm_hour,
             &tm.tm_min, &tm.tm_sec, &n) != 6 || s[n] != 0)
    return -1;
  tm.tm_year -= 1900;
  tm.tm_mon -= 1;
  *t = (long long)timegm(&tm);
  return 0;
}

/* Write index.yaml from the entries (sorted first). Caller holds the lock. */
static int index_write(gr_kb *kb, entries *es, gr_err *e) {
  if (es->n) qsort(es->v, es->n, sizeof *es->v, entry_cmp);
  wbuf w = {0};
  w_str(&w, "# Gradus knowledge base index: a cache, rebuilt from t/*.gtp when missing or damaged.\n");
  w_str(&w, "format: 1\n");
  w_str(&w, es->n ? "templates:\n" : "templates: []\n");
  for (size_t i = 0; i < es->n; i++) {
    const gr_kb_entry *x = &es->v[i];
    char b[256], tm[32];
    fmt_time(x->created, tm);
    snprintf(b, sizeof b, "  - key: %s\n    signature: ", x->key);
    w_str(&w, b);
    w_quoted(&w, x->signature);
    snprintf(b, sizeof b, "\n    file: t/%s.gtp\n    bytes: %zu\n    created: %s\n    qualified: %s\n    quality: [",
             x->key, x->bytes, tm, x->qualified ? "true" : "false");
    w_str(&w, b);
    for (int k = 0; k < GR_TEMPLATE_NQ; k++) {
      if (k) w_str(&w, ", ");
      w_fmt_double(&w, x->quality[k]);
    }
    w_str(&w, "]\n");
  }
  if (w.fail) { free(w.p); return gr_fail(e, GR_EMEM, "out of memory writing the index"); }
  char *path = join(kb->dir, "index.yaml");
  int rc = path ? write_atomic(path, w.p, w.n, e) : gr_fail(e, GR_EMEM, "out of memory");
  free(path);
  free(w.p);
  return rc;
}

/* Undo w_quoted. Returns a new string or NULL when malformed. */
static char *unquote(const char *s) {
  size_t n = strlen(s);
  if (n < 2 || s[0] != '"' || s[n - 1] != '"') return NULL;
  char *o = malloc(n), *q = o;
  if (!o) return NULL;
  for (size_t i = 1; i < n - 1; i++) {
    if (s[i] == '"') { free(o); return NULL; }
    if (s[i] != '\\') { *q++ = s[i]; continue; }
    if (++i >= n - 1) { free(o); return NULL; }
    switch (s[i]) {
      case '"': *q++ = '"'; break;
      case '\\': *q++ = '\\'; break;
      case 'n': *q++ = '\n'; break;
      case 't': *q++ = '\t'; break;
      case 'r': *q++ = '\r'; break;
      case 'x': {
        unsigned v;
        if (i + 2 >= n - 1 || sscanf(s + i + 1, "%2x", &v) != 1 || v == 0) { free(o); return NULL; }
        *q++ = (char)v;
        i += 2;
        break;
      }
      default: free(o); return NULL;
    }
  }
  *q = 0;
  return o;
}

static int parse_double(const char *s, double *d) {
  if (!strcmp(s, ".nan")) { *d = NAN; return 0; }
  if (!strcmp(s, ".inf")) { *d = INFINITY; return 0; }
  if (!strcmp(s, "-.inf")) { *d = -INFINITY; return 0; }
  char *end;
  *d = strtod(s, &end);
  return (end == s || *end) ? -1 : 0;
}

/* Parse the index as written by index_write. Returns 0 and fills es, or -1
 * (es emptied) when the file is missing or is not exactly that format. */
static int index_read(const gr_kb *kb, entries *es) {
  es->v = NULL;
  es->n = es->cap = 0;
  char *path = join(kb->dir, "index.yaml");
  unsigned char *buf = NULL;
  size_t n = 0;
  int err = path ? read_all(path, &buf, &n) : ENOMEM;
  free(path);
  if (err) return -1;
  buf[n] = 0; /* read_all leaves one spare byte */
  if (memchr(buf, 0, n)) { free(buf); return -1; }
  enum { F_KEY = 1, F_SIG = 2, F_FILE = 4, F_BYTES = 8, F_CREATED = 16, F_QUAL = 32, F_QUALITY = 64, F_ALL = 127 };
  int ok = 1, seen_format = 0, seen_templates = 0, empty_list = 0, fields = F_ALL;
  gr_kb_entry *x = NULL;
  char *line = (char *)buf;
  while (ok && line && *line) {
    char *nl = strchr(line, '\n');
    if (nl) *nl = 0;
    char *next = nl ? nl + 1 : NULL;
    if (line[0] == '#' || line[0] == 0) { line = next; continue; }
    if (!strcmp(line, "format: 1")) seen_format = 1;
    else if (!strcmp(line, "templates:") && seen_format && !seen_templates) seen_templates = 1;
    else if (!strcmp(line, "templates: []") && seen_format && !seen_templates) seen_templates = empty_list = 1;
    else if (!strncmp(line, "  - key: ", 9) && seen_templates && !empty_list) {
      if (fields != F_ALL) { ok = 0; break; }
      if (!valid_key(line + 9) || entries_find(es, line + 9)) { ok = 0; break; }
      if (gr_grow(&es->v, &es->cap, es->n + 1, sizeof *es->v)) { ok = 0; break; }
      x = &es->v[es->n++];
      memset(x, 0, sizeof *x);
      memcpy(x->key, line + 9, 65);
      fields = F_KEY;
    } else if (x && !strncmp(line, "    signature: ", 15) && !(fields & F_SIG)) {
      ok = (x->signature = unquote(line + 15)) != NULL;
      fields |= F_SIG;
    } else if (x && !strncmp(line, "    file: ", 10) && !(fields & F_FILE)) {
      char want[80];
      snprintf(want, sizeof want, "t/%s.gtp", x->key);
      ok = !strcmp(line + 10, want);
      fields |= F_FILE;
    } else if (x && !strncmp(line, "    bytes: ", 11) && !(fields & F_BYTES)) {
      char *end;
      errno = 0;
      unsigned long long v = strtoull(line + 11, &end, 10);
      ok = end != line + 11 && !*end && !errno && line[11] != '-';
      x->bytes = (size_t)v;
      fields |= F_BYTES;
    } else if (x && !strncmp(line, "    created: ", 13) && !(fields & F_CREATED)) {
      ok = parse_time(line + 13, &x->created) == 0;
      fields |= F_CREATED;
    } else if (x && !strncmp(line, "    qualified: ", 15) && !(fields & F_QUAL)) {
      ok = !strcmp(line + 15, "true") || !strcmp(line + 15, "false");
      x->qualified = !strcmp(line + 15, "true");
      fields |= F_QUAL;
    } else if (x && !strncmp(line, "    quality: [", 14) && !(fields & F_QUALITY)) {
      char *s = line + 14, *end = strchr(s, ']');
      ok = end && end[1] == 0;
      if (ok) *end = 0;
      for (int k = 0; ok && k < GR_TEMPLATE_NQ; k++) {
        char *comma = strchr(s, ',');
        if ((k < GR_TEMPLATE_NQ - 1) != (comma != NULL)) { ok = 0; break; }
        if (comma) *comma = 0;
        while (*s == ' ') s++;
        ok = parse_double(s, &x->quality[k]) == 0;
        s = comma ? comma + 1 : s;
      }
      fields |= F_QUALITY;
    } else ok = 0;
    line = next;
  }
  ok = ok && seen_format && seen_templates && fields == F_ALL;
  free(buf);
  if (!ok) {
    gr_kb_entries_free(es->v, es->n);
    es->v = NULL;
    es->n = es->cap = 0;
    return -1;
  }
  if (es->n) qsort(es->v, es->n, sizeof *es->v, entry_cmp);
  return 0;
}

/* ---- directory scans ---- */
typedef struct names {
  char **v;
  size_t n, cap;
} names;

static void names_free(names *ns) {
  for (size_t i = 0; i < ns->n; i++) free(ns->v[i]);
  free(ns->v);
  ns->v = NULL;
  ns->n = ns->cap = 0;
}

static int names_cmp(const void *a, const void *b) {
  return strcmp(*(char *const *)a, *(char *const *)b);
}

/* File names in `dir` (no "." or ".."), sorted. GR_OK or GR_EIO/GR_EMEM. */
static int list_dir(const char *dir, names *ns, gr_err *e) {
  ns->v = NULL;
  ns->n = ns->cap = 0;
  DIR *d = opendir(dir);
  if (!d) return gr_fail(e, GR_EIO, "cannot read directory %s: %s", dir, strerror(errno));
  struct dirent *de;
  while ((de = readdir(d))) {
    if (!strcmp(de->d_name, ".") || !strcmp(de->d_name, "..")) continue;
    char *s = strdup(de->d_name);
    if (!s || gr_grow(&ns->v, &ns->cap, ns->n + 1, sizeof *ns->v)) {
      free(s);
      closedir(d);
      names_free(ns);
      return gr_fail(e, GR_EMEM, "out of memory listing %s", dir);
    }
    ns->v[ns->n++] = s;
  }
  closedir(d);
  if (ns->n) qsort(ns->v, ns->n, sizeof *ns->v, names_cmp);
  return GR_OK;
}

static int is_temp_name(const char *s) { return strstr(s, ".tmp-") != NULL; }

/* "<64 hex>.gtp" -> key in k; else 0. */
static int blob_name_key(const char *s, char k[65]) {
  size_t n = strlen(s);
  if (n != 68 || strcmp(s + 64, ".gtp") != 0) return 0;
  memcpy(k, s, 64);
  k[64] = 0;
  return valid_key(k);
}

static int has_suffix(const char *s, const char *suf) {
  size_t n = strlen(s), m = strlen(suf);
  return n >= m && !strcmp(s + n - m, suf);
}

typedef struct msgs {
  char *p;
  size_t n, cap;
} msgs;

static void msg_add(msgs *m, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void msg_add(msgs *m, const char *fmt, ...) {
  char b[768];
  va_list ap;
  va_start(ap, fmt);
  int k = vsnprintf(b, sizeof b, fmt, ap);
  va_end(ap);
  if (k < 0) return;
  size_t len = strlen(b);
  if (gr_grow(&m->p, &m->cap, m->n + len + 2, 1)) return;
  memcpy(m->p + m->n, b, len);
  m->n += len;
  m->p[m->n++] = '\n';
  m->p[m->n] = 0;
}

/* Called for each blob while scanning t/ (name, key or "" for a bad name,
 * the template or NULL, the defect when damaged). */
typedef void (*blob_fn)(void *ctx, const char *name, const char *key, gr_template *t,
                        size_t bytes, const char *defect);

/* Visit every *.gtp in t/, fully decoded. Temporary names are skipped. */
static int scan_blobs(gr_kb *kb, blob_fn fn, void *ctx, gr_err *e) {
  char *td = join(kb->dir, "t");
  if (!td) return gr_fail(e, GR_EMEM, "out of memory");
  names ns;
  int rc = list_dir(td, &ns, e);
  free(td);
  if (rc) return rc;
  for (size_t i = 0; i < ns.n && rc == GR_OK; i++) {
    const char *nm = ns.v[i];
    if (is_temp_name(nm) || !has_suffix(nm, ".gtp")) continue;
    char key[65];
    if (!blob_name_key(nm, key)) {
      fn(ctx, nm, "", NULL, 0, "file name is not <64 hex digits>.gtp");
      continue;
    }
    gr_template *t = NULL;
    size_t bytes = 0;
    int absent;
    gr_err e2;
    gr_err_clear(&e2);
    int lr = load_blob(kb, key, &t, &bytes, &absent, &e2);
    if (lr == GR_EMEM) rc = gr_fail(e, lr, "%s", e2.msg);
    else if (absent) continue; /* removed meanwhile */
    else fn(ctx, nm, key, t, bytes, lr == GR_OK ? NULL : e2.msg);
    gr_template_free(t);
  }
  names_free(&ns);
  return rc;
}

typedef struct rebuild_ctx {
  entries es;
  msgs *m;
  int fail;
} rebuild_ctx;

static void rebuild_fn(void *ctx, const char *name, const char *key, gr_template *t,
                       size_t bytes, const char *defect) {
  rebuild_ctx *c = ctx;
  (void)key;
  if (!t) {
    if (c->m) msg_add(c->m, "t/%s: damaged (%s); left out of the index", name, defect);
    return;
  }
  if (entries_set(&c->es, t, t->created, bytes)) c->fail = 1;
}

/* Rebuild the index from the blobs and write it; the lock is held. On
 * success *es holds the entries (caller frees). */
static int index_rebuild(gr_kb *kb, entries *es, msgs *m, gr_err *e) {
  rebuild_ctx c = {{NULL, 0, 0}, m, 0};
  int rc = scan_blobs(kb, rebuild_fn, &c, e);
  if (rc == GR_OK && c.fail) rc = gr_fail(e, GR_EMEM, "out of memory rebuilding the index");
  if (rc == GR_OK) rc = index_write(kb, &c.es, e);
  if (rc != GR_OK) {
    gr_kb_entries_free(c.es.v, c.es.n);
    return rc;
  }
  *es = c.es;
  return GR_OK;
}

int gr_kb_put(gr_kb *kb, const gr_template *t, gr_err *e) {
  if (!kb) return gr_fail(e, GR_EARG, "knowledge base is NULL");
  long long created = t && t->created ? t->created : (long long)time(NULL);
  unsigned char *buf;
  size_t n;
  int rc = encode_blob(t, created, &buf, &n, e);
  if (rc) return rc;
  char *path = blob_path(kb, t->key);
  if (!path) { free(buf); return gr_fail(e, GR_EMEM, "out of memory"); }
  int fd = lock_take(kb, e);
  if (fd < 0) { free(buf); free(path); return GR_EIO; }
  rc = write_atomic(path, buf, n, e);
  free(buf);
  free(path);
  if (rc == GR_OK) {
    entries es = {NULL, 0, 0};
    if (index_read(kb, &es) != 0) {
      rc = index_rebuild(kb, &es, NULL, e); /* includes the blob just written */
    } else {
      rc = entries_set(&es, t, created, n) ? gr_fail(e, GR_EMEM, "out of memory") : GR_OK;
      if (rc == GR_OK) rc = index_write(kb, &es, e);
    }
    gr_kb_entries_free(es.v, es.n);
  }
  lock_drop(kb, fd);
  return rc;
}

/* 1 if the index lists exactly the *.gtp files of t/ with their sizes. */
static int index_matches_dir(const gr_kb *kb, const entries *es) {
  char *td = join(kb->dir, "t");
  if (!td) return 0;
  names ns;
  gr_err e2;
  int ok = list_dir(td, &ns, &e2) == GR_OK;
  size_t nblobs = 0;
  for (size_t i = 0; ok && i < ns.n; i++) {
    const char *nm = ns.v[i];
    if (is_temp_name(nm) || !has_suffix(nm, ".gtp")) continue;
    char key[65];
    if (!blob_name_key(nm, key)) continue; /* foreign names are never listed */
    nblobs++;
    const gr_kb_entry *x = NULL;
    for (size_t k = 0; k < es->n && !x; k++)
      if (!strcmp(es->v[k].key, key)) x = &es->v[k];
    struct stat st;
    char *p = join(td, nm);
    ok = x && p && stat(p, &st) == 0 && (uint64_t)st.st_size == (uint64_t)x->bytes;
    free(p);
  }
  if (ok) ok = nblobs == es->n;
  names_free(&ns);
  free(td);
  return ok;
}

int gr_kb_list(gr_kb *kb, gr_kb_entry **out, size_t *n, char *warning, size_t wn,
               gr_err *e) {
  *out = NULL;
  *n = 0;
  if (warning && wn) warning[0] = 0;
  entries es;
  if (index_read(kb, &es) == 0 && index_matches_dir(kb, &es)) {
    *out = es.v;
    *n = es.n;
    return GR_OK;
  }
  gr_kb_entries_free(es.v, es.n);
  int fd = lock_take(kb, e);
  if (fd < 0) return GR_EIO;
  msgs m = {0};
  int rc = index_rebuild(kb, &es, &m, e);
  lock_drop(kb, fd);
  if (warning && wn && m.n) {
    if (m.p[m.n - 1] == '\n') m.p[m.n - 1] = 0;
    snprintf(warning, wn, "%s", m.p);
  }
  free(m.p);
  if (rc) return rc;
  *out = es.v;
  *n = es.n;
  return GR_OK;
}

void gr_kb_report_clear(gr_kb_report *r) {
  if (!r) return;
  free(r->messages);
  memset(r, 0, sizeof *r);
}

/* Count (and with `remove`, delete) orphan temporaries in dir and dir/t. */
static int sweep_temps(gr_kb *kb, int remove, gr_kb_report *r, msgs *m, gr_err *e) {
  const char *subs[2] = {"", "t"};
  for (int s = 0; s < 2; s++) {
    char *d = *subs[s] ? join(kb->dir, subs[s]) : strdup(kb->dir);
    if (!d) return gr_fail(e, GR_EMEM, "out of memory");
    names ns;
    int rc = list_dir(d, &ns, e);
    if (rc) { free(d); return rc; }
    for (size_t i = 0; i < ns.n; i++) {
      if (!is_temp_name(ns.v[i])) continue;
      r->orphans++;
      char *p = join(d, ns.v[i]);
      if (remove && p && unlink(p) == 0) {
        r->removed++;
        msg_add(m, "%s%s%s: orphan temporary file removed", subs[s], *subs[s] ? "/" : "", ns.v[i]);
      } else {
        msg_add(m, "%s%s%s: orphan temporary file%s", subs[s], *subs[s] ? "/" : "", ns.v[i],
                remove ? " (cannot remove)" : "");
      }
      free(p);
    }
    names_free(&ns);
    free(d);
  }
  return GR_OK;
}

typedef struct verify_ctx {
  gr_kb_report *r;
  msgs *m;
  entries good;       /* blobs that passed */
  int fail;
  /* prune only */
  gr_kb *kb;
  const gr_kb_prune_opts *opts;
  int prune;
} verify_ctx;

static int in_keep(const gr_kb_prune_opts *o, const char *key) {
  for (size_t i = 0; i < o->nkeep; i++)
    if (o->keep[i] && !strcmp(o->keep[i], key)) return 1;
  return 0;
}

static void verify_fn(void *ctx, const char *name, const char *key, gr_template *t,
                      size_t bytes, const char *defect) {
  verify_ctx *c = ctx;
  const char *why = NULL;
  if (!t) {
    c->r->corrupt++;
    why = defect;
  } else if (c->prune && c->opts && c->opts->older_than > 0 && t->created < c->opts->older_than) {
    why = "older than the age limit";
  } else if (c->prune && c->opts && c->opts->use_keep && !in_keep(c->opts, key)) {
    why = "not in the keep-set";
  }
  if (!why) {
    c->r->ok++;
    if (entries_set(&c->good, t, t->created, bytes)) c->fail = 1;
    return;
  }
  if (!c->prune) {
    msg_add(c->m, "t/%s: damaged: %s", name, why);
    return;
  }
  char *td = join(c->kb->dir, "t");
  char *p = td ? join(td, name) : NULL;
  if (p && unlink(p) == 0) {
    c->r->removed++;
    msg_add(c->m, "t/%s: removed (%s)", name, why);
  } else {
    msg_add(c->m, "t/%s: cannot remove (%s): %s", name, why, strerror(errno));
  }
  free(p);
  free(td);
}

int gr_kb_verify(gr_kb *kb, gr_kb_report *r, gr_err *e) {
  memset(r, 0, sizeof *r);
  int fd = lock_take(kb, e);
  if (fd < 0) return GR_EIO;
  msgs m = {0};
  verify_ctx c = {r, &m, {NULL, 0, 0}, 0, kb, NULL, 0};
  int rc = sweep_temps(kb, 0, r, &m, e);
  if (rc == GR_OK) rc = scan_blobs(kb, verify_fn, &c, e);
  if (rc == GR_OK && c.fail) rc = gr_fail(e, GR_EMEM, "out of memory verifying");
  if (rc == GR_OK) {
    entries idx;
    if (index_read(kb, &idx) != 0) {
      msg_add(&m, "index.yaml: missing or unreadable (it is rebuilt by the next list or put)");
    } else {
      r->index_entries = idx.n;
      int same = idx.n == c.good.n;
      if (c.good.n) qsort(c.good.v, c.good.n, sizeof *c.good.v, entry_cmp);
      for (size_t i = 0; same && i < idx.n; i++) { /* both sorted by key */
        same = !strcmp(idx.v[i].key, c.good.v[i].key) && idx.v[i].bytes == c.good.v[i].bytes;
      }
      r->index_ok = same;
      if (!same) msg_add(&m, "index.yaml: does not match the blobs (it is rebuilt by the next list)");
      gr_kb_entries_free(idx.v, idx.n);
    }
  }
  lock_drop(kb, fd);
  gr_kb_entries_free(c.good.v, c.good.n);
  r->messages = m.p;
  return rc;
}

int gr_kb_prune(gr_kb *kb, const gr_kb_prune_opts *opts, gr_kb_report *r, gr_err *e) {
  memset(r, 0, sizeof *r);
  int fd = lock_take(kb, e);
  if (fd < 0) return GR_EIO;
  msgs m = {0};
  verify_ctx c = {r, &m, {NULL, 0, 0}, 0, kb, opts, 1};
  int rc = sweep_temps(kb, 1, r, &m, e);
  if (rc == GR_OK) rc = scan_blobs(kb, verify_fn, &c, e);
  if (rc == GR_OK && c.fail) rc = gr_fail(e, GR_EMEM, "out of memory pruning");
  if (rc == GR_OK) rc = index_write(kb, &c.good, e);
  if (rc == GR_OK) {
    r->index_entries = c.good.n;
    r->index_ok = 1;
  }
  lock_drop(kb, fd);
  gr_kb_entries_free(c.good.v, c.good.n);
  r->messages = m.p;
  return rc;
}
