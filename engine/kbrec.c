/* kbrec.c: SHA-256 (through nettle) and the knowledge base's template records (.gtp codec),
 * see kb.h and doc/formats.md. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "kbbuf.h"
#include "kbint.h"

/* ================================================================ SHA-256 */
/* The digest comes from nettle (Debian's nettle-dev, libnettle): the same
 * FIPS 180-4 SHA-256 as our earlier own code, so every stored key and
 * checksum still verifies. */
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

int gr_kb_valid_key(const char *k) {
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

/* ---- blob header ---- */
#define GTP_MAGIC "GRADUSTP"
#define GTP_VERSION 1u
#define GTP_HEADER 56u /* magic 8 + version 4 + header size 4 + payload length 8 + sha 32 */

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
int gr_kb_encode_blob(const gr_template *t, long long created, unsigned char **buf,
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
  return gr_kb_encode_blob(t, t ? t->created : 0, buf, n, e);
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
  if (!gr_kb_valid_key(key)) return gr_fail(e, GR_EPARSE, "stored key is not 64 lowercase hex digits");
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

