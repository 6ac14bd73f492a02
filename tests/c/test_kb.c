/* test_kb.c: SHA-256 against the FIPS 180-4 examples, template encode/decode,
 * and the knowledge base directory: round trips, damaged blobs, index
 * rebuild, concurrent writers (fork and threads), prune. */
#include "check.h"
#include "kb.h"
#include "kbwriter.h"
#include <dirent.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

static const double PI = 3.14159265358979323846;

/* ---- helpers ---- */
static char *tmpdir(void) {
  char tmpl[] = "/tmp/gradus_kb_XXXXXX";
  char *d = mkdtemp(tmpl);
  return d ? strdup(d) : NULL;
}

static void rm_rf(const char *path) {
  DIR *d = opendir(path);
  if (d) {
    struct dirent *de;
    while ((de = readdir(d))) {
      if (!strcmp(de->d_name, ".") || !strcmp(de->d_name, "..")) continue;
      char p[4096];
      snprintf(p, sizeof p, "%s/%s", path, de->d_name);
      rm_rf(p);
    }
    closedir(d);
    rmdir(path);
  } else {
    unlink(path);
  }
}

static int file_exists(const char *p) {
  struct stat st;
  return stat(p, &st) == 0;
}

/* Files whose name contains ".tmp-" in dir and dir/t. */
static int count_temps(const char *dir) {
  int n = 0;
  for (int s = 0; s < 2; s++) {
    char p[4096];
    snprintf(p, sizeof p, "%s%s", dir, s ? "/t" : "");
    DIR *d = opendir(p);
    if (!d) continue;
    struct dirent *de;
    while ((de = readdir(d)))
      if (strstr(de->d_name, ".tmp-")) n++;
    closedir(d);
  }
  return n;
}

static int write_file(const char *path, const void *data, size_t n) {
  FILE *f = fopen(path, "wb");
  if (!f) return -1;
  size_t k = fwrite(data, 1, n, f);
  fclose(f);
  return k == n ? 0 : -1;
}

static unsigned char *read_file(const char *path, size_t *n) {
  *n = 0;
  FILE *f = fopen(path, "rb");
  if (!f) return NULL;
  fseek(f, 0, SEEK_END);
  long sz = ftell(f);
  fseek(f, 0, SEEK_SET);
  unsigned char *p = malloc(sz > 0 ? (size_t)sz : 1);
  *n = fread(p, 1, (size_t)sz, f);
  fclose(f);
  return p;
}

static void blob_file(char *out, size_t n, const char *dir, const char *key) {
  snprintf(out, n, "%s/t/%s.gtp", dir, key);
}

/* Regular m-gon of radius r about (cx, cy), CCW (ccw = 1) or CW. */
static void add_polygon(gr_rings *g, int m, double r, double cx, double cy, int ccw) {
  double *xy = malloc(2 * (size_t)m * sizeof *xy);
  for (int i = 0; i < m; i++) {
    double a = 2 * PI * i / m * (ccw ? 1 : -1);
    xy[2 * i] = cx + r * cos(a);
    xy[2 * i + 1] = cy + r * sin(a);
  }
  gr_rings_add(g, xy, (size_t)m);
  free(xy);
}

static double polygon_area(int m, double r) { return 0.5 * m * r * r * sin(2 * PI / m); }

/* A template whose content depends on `id`: nl layers of 3 slots, slot 0 an
 * annulus (outer 24-gon radius 1+id/100, hole 12-gon radius 0.4), slot 1 one
 * square, slot 2 empty; extra scans when with_extra. */
static gr_template *make_template(int id, int nl, int with_extra) {
  char sig[128];
  snprintf(sig, sizeof sig, "{type: gyroid, cell: [2, 2, 2], t: %.3f, id: %d, note: \"é\\n\"}",
           0.1 + 0.001 * id, id);
  gr_err e;
  gr_template *t = gr_template_new(sig, nl, 3, with_extra, &e);
  if (!t) return NULL;
  for (int l = 0; l < nl; l++) {
    t->z[l] = 0.03 * (l + 0.5);
    gr_rings *s0 = gr_template_rings(t, l, 0);
    add_polygon(s0, 24, 1 + id / 100.0, 0, 0, 1);
    add_polygon(s0, 12, 0.4, 0, 0, 0);
    gr_rings_nest(s0, &e);
    double sq[8] = {-0.5, -0.5, 0.5, -0.5, 0.5, 0.5, -0.5, 0.5};
    gr_rings_add(gr_template_rings(t, l, 1), sq, 4);
    if (with_extra) {
      gr_layer *x = t->extra[l];
      x->z = t->z[l];
      x->thin_walls = l % 2;
      x->area = 0.25 * l;
      gr_layer_add_segment(x, GR_HATCH, 1, -0.5, 0.1 * l, 0.5, 0.1 * l);
      gr_layer_add_segment(x, GR_HATCH, 1, 0.5, 0.2, -0.5, 0.2);
      double cl[6] = {0, 0, 0.1, 0.2, 0.3, -0.1};
      gr_layer_add(x, GR_OPEN, GR_EDGE, 0, 2, cl, 3);
    }
  }
  for (int k = 0; k < GR_TEMPLATE_NQ; k++) t->quality[k] = k == 3 ? NAN : 0.5 * k + id;
  t->quality[5] = INFINITY;
  t->qualified = id % 2;
  t->created = 1700000000 + id;
  gr_template_set_meta(t, "gradus: 0.1.0\nparams: {hatch: 0.08}\n", &e);
  return t;
}

static int same_double(double a, double b) { return memcmp(&a, &b, sizeof a) == 0; }

/* 1 if a and b hold bit-identical content. */
static int same_template(const gr_template *a, const gr_template *b) {
  if (strcmp(a->key, b->key) || strcmp(a->signature, b->signature)) return 0;
  if (a->nlayers != b->nlayers || a->nslots != b->nslots) return 0;
  if ((a->meta == NULL) != (b->meta == NULL) || (a->meta && strcmp(a->meta, b->meta))) return 0;
  if (a->qualified != b->qualified || a->created != b->created) return 0;
  for (int k = 0; k < GR_TEMPLATE_NQ; k++)
    if (!same_double(a->quality[k], b->quality[k])) return 0;
  for (int l = 0; l < a->nlayers; l++) {
    if (!same_double(a->z[l], b->z[l])) return 0;
    for (int s = 0; s < a->nslots; s++) {
      const gr_rings *x = gr_template_rings(a, l, s), *y = gr_template_rings(b, l, s);
      if (x->nrings != y->nrings || x->npts != y->npts) return 0;
      if (memcmp(x->start, y->start, (x->nrings + 1) * sizeof *x->start)) return 0;
      if (x->npts && memcmp(x->xy, y->xy, 2 * x->npts * sizeof *x->xy)) return 0;
      if ((x->parent == NULL) != (y->parent == NULL)) return 0;
      if (x->parent && memcmp(x->parent, y->parent, x->nrings * sizeof *x->parent)) return 0;
    }
  }
  if ((a->extra == NULL) != (b->extra == NULL)) return 0;
  if (a->extra)
    for (int l = 0; l < a->nlayers; l++) {
      const gr_layer *x = a->extra[l], *y = b->extra[l];
      if (!same_double(x->z, y->z) || !same_double(x->area, y->area)) return 0;
      if (x->thin_walls != y->thin_walls || x->npts != y->npts || x->nb != y->nb) return 0;
      if (x->npts && memcmp(x->xy, y->xy, 2 * x->npts * sizeof *x->xy)) return 0;
      for (size_t i = 0; i < x->nb; i++)
        if (x->b[i].shape != y->b[i].shape || x->b[i].kind != y->b[i].kind ||
            x->b[i].laser != y->b[i].laser || x->b[i].dir != y->b[i].dir ||
            x->b[i].start != y->b[i].start || x->b[i].n != y->b[i].n)
          return 0;
    }
  return 1;
}

/* ---- SHA-256 ---- */
TEST(sha256_vectors) {
  char h[65];
  gr_sha256_hex("", 0, h);
  CHECK(!strcmp(h, "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855"), "%s", h);
  gr_sha256_hex("abc", 3, h);
  CHECK(!strcmp(h, "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"), "%s", h);
  const char *m2 = "abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq";
  gr_sha256_hex(m2, strlen(m2), h);
  CHECK(!strcmp(h, "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1"), "%s", h);
  const char *m3 = "abcdefghbcdefghicdefghijdefghijkefghijklfghijklmghijklmnhijklmnoijklmnopjklmnopqklmnopqrlmnopqrsmnopqrstnopqrstu";
  gr_sha256_hex(m3, strlen(m3), h);
  CHECK(!strcmp(h, "cf5b16a778af8380036ce59e7b0492370b249b11e8f07a51afac45037afee9d1"), "%s", h);
  /* one million 'a', fed in uneven pieces to exercise the block buffer */
  gr_sha256 s;
  unsigned char d[32];
  char a[997];
  memset(a, 'a', sizeof a);
  gr_sha256_init(&s);
  size_t left = 1000000, piece = 1;
  while (left) {
    size_t k = piece < left ? piece : left;
    gr_sha256_update(&s, a, k);
    left -= k;
    piece = piece % 990 + 7;
  }
  gr_sha256_final(&s, d);
  static const char hx[] = "0123456789abcdef";
  for (int i = 0; i < 32; i++) { h[2 * i] = hx[d[i] >> 4]; h[2 * i + 1] = hx[d[i] & 15]; }
  h[64] = 0;
  CHECK(!strcmp(h, "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0"), "%s", h);
  /* 55, 56 and 64 bytes straddle the padding boundary: compare one-shot with
   * byte-at-a-time */
  for (size_t n = 50; n <= 70; n++) {
    char one[65], two[65];
    gr_sha256_hex(a, n, one);
    gr_sha256_init(&s);
    for (size_t i = 0; i < n; i++) gr_sha256_update(&s, a, 1);
    gr_sha256_final(&s, d);
    for (int i = 0; i < 32; i++) { two[2 * i] = hx[d[i] >> 4]; two[2 * i + 1] = hx[d[i] & 15]; }
    two[64] = 0;
    CHECK(!strcmp(one, two), "n = %zu", n);
  }
}

/* ---- templates ---- */
TEST(template_new_args) {
  gr_err e;
  CHECK(gr_template_new(NULL, 1, 1, 0, &e) == NULL && e.code == GR_EARG, "NULL signature");
  CHECK(gr_template_new("x", -1, 1, 0, &e) == NULL && strstr(e.msg, "-1"), "%s", e.msg);
  CHECK(gr_template_new("x", 1, 0, 0, &e) == NULL && strstr(e.msg, "nslots"), "%s", e.msg);
  gr_template *t = gr_template_new("abc", 0, 1, 1, &e);
  CHECK(t && !strcmp(t->key, "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"),
        "key is SHA-256 of the signature");
  CHECK(t && isnan(t->quality[0]), "quality starts unknown");
  gr_template_free(t);
  gr_template_free(NULL);
}

TEST(encode_decode_roundtrip) {
  gr_err e;
  for (int extra = 0; extra <= 1; extra++) {
    gr_template *t = make_template(7, 4, extra);
    CHECK(t != NULL, "make");
    unsigned char *buf;
    size_t n;
    CHECK(gr_template_encode(t, &buf, &n, &e) == GR_OK, "%s", e.msg);
    CHECK(n > 56 && !memcmp(buf, "GRADUSTP", 8), "magic");
    gr_template *u = NULL;
    CHECK(gr_template_decode(buf, n, &u, &e) == GR_OK, "%s", e.msg);
    CHECK(u && same_template(t, u), "bit-identical after decode (extra %d)", extra);
    if (u) {
      /* the geometry is intact: annulus area, parent of the hole */
      const gr_rings *s0 = gr_template_rings(u, 2, 0);
      CHECK_NEAR(gr_rings_area(s0), polygon_area(24, 1.07) - polygon_area(12, 0.4), 1e-12);
      CHECK(s0->parent && s0->parent[0] == -1 && s0->parent[1] == 0, "nesting kept");
      CHECK_NEAR(gr_rings_area(gr_template_rings(u, 0, 1)), 1.0, 1e-15);
      CHECK(gr_template_rings(u, 3, 2)->nrings == 0, "empty slot stays empty");
      if (extra) {
        gr_layer_stats st;
        gr_layer_stats_get(u->extra[1], &st);
        CHECK(st.vectors[GR_HATCH] == 2, "two hatch vectors, got %zu", st.vectors[GR_HATCH]);
        CHECK_NEAR(st.length[GR_HATCH], 2.0, 1e-15);
      }
    }
    /* encoding is deterministic */
    unsigned char *buf2;
    size_t n2;
    CHECK(gr_template_encode(u, &buf2, &n2, &e) == GR_OK && n2 == n && !memcmp(buf, buf2, n),
          "re-encode identical");
    free(buf2);
    gr_template_free(u);
    free(buf);
    gr_template_free(t);
  }
  /* a key that does not match the signature is refused */
  gr_template *t = make_template(1, 1, 0);
  t->key[0] = t->key[0] == '0' ? '1' : '0';
  unsigned char *buf;
  size_t n;
  CHECK(gr_template_encode(t, &buf, &n, &e) == GR_EARG && strstr(e.msg, "key"), "%s", e.msg);
  gr_template_free(t);
}

/* Re-seal a blob after editing its payload, so that structural checks (not
 * the checksum) must catch the edit. */
static void reseal(unsigned char *buf, size_t n) {
  gr_sha256 s;
  gr_sha256_init(&s);
  gr_sha256_update(&s, buf + 56, n - 56);
  gr_sha256_final(&s, buf + 24);
}

TEST(decode_rejects_damage) {
  gr_err e;
  gr_template *t = make_template(3, 2, 1), *u = NULL;
  unsigned char *buf;
  size_t n;
  CHECK(gr_template_encode(t, &buf, &n, &e) == GR_OK, "%s", e.msg);
  int bad = 0;
  for (size_t k = 0; k < n; k++) /* every truncation */
    if (gr_template_decode(buf, k, &u, &e) != GR_EPARSE || u) bad++;
  CHECK(bad == 0, "%d truncations accepted", bad);
  bad = 0;
  for (size_t k = 0; k < n; k++) { /* every single-bit flip */
    buf[k] ^= 0x10;
    if (gr_template_decode(buf, n, &u, &e) != GR_EPARSE || u) bad++;
    buf[k] ^= 0x10;
  }
  CHECK(bad == 0, "%d bit flips accepted", bad);
  buf[3] ^= 1;
  gr_template_decode(buf, n, &u, &e);
  CHECK(strstr(e.msg, "magic"), "%s", e.msg);
  buf[3] ^= 1;
  buf[8] = 9;
  gr_template_decode(buf, n, &u, &e);
  CHECK(strstr(e.msg, "version 9"), "%s", e.msg);
  buf[8] = 1;
  buf[100] ^= 1;
  gr_template_decode(buf, n, &u, &e);
  CHECK(strstr(e.msg, "checksum"), "%s", e.msg);
  buf[100] ^= 1;
  /* a consistent checksum over a nonsense count: nslots = 2^31 */
  unsigned char *c = malloc(n);
  memcpy(c, buf, n);
  c[56 + 4 + 3] = 0x80;
  reseal(c, n);
  CHECK(gr_template_decode(c, n, &u, &e) == GR_EPARSE && !u, "huge nslots: %s", e.msg);
  /* the first ring set claims 2^60 rings: offset = header fields 24 + quality
   * 64 + key 64 + siglen 4 + sig + metalen 4 + meta + z */
  memcpy(c, buf, n);
  size_t off = 56 + 24 + 64 + 64 + 4 + strlen(t->signature) + 4 + strlen(t->meta) + 8 * 2;
  CHECK(c[off] == 2 && c[off + 8] == 36, "ring set header where doc/kb.md says");
  c[off + 7] = 0x10;
  reseal(c, n);
  CHECK(gr_template_decode(c, n, &u, &e) == GR_EPARSE && !u && strstr(e.msg, "rings"), "%s", e.msg);
  /* a ring of length 0 */
  memcpy(c, buf, n);
  c[off + 20] = 0;
  reseal(c, n);
  CHECK(gr_template_decode(c, n, &u, &e) == GR_EPARSE && strstr(e.msg, "length"), "%s", e.msg);
  /* trailing garbage with a matching header */
  unsigned char *g = malloc(n + 3);
  memcpy(g, buf, n);
  g[n] = g[n + 1] = g[n + 2] = 7;
  uint64_t plen = n + 3 - 56;
  for (int i = 0; i < 8; i++) g[16 + i] = (unsigned char)(plen >> (8 * i));
  reseal(g, n + 3);
  CHECK(gr_template_decode(g, n + 3, &u, &e) == GR_EPARSE && strstr(e.msg, "unexpected"), "%s", e.msg);
  free(g);
  free(c);
  free(buf);
  gr_template_free(t);
}

/* ---- the store ---- */
TEST(default_dir) {
  char d[256];
  const char *h = getenv("HOME");
  char *home = h ? strdup(h) : NULL, *gc = getenv("GRADUS_CACHE_DIR") ? strdup(getenv("GRADUS_CACHE_DIR")) : NULL;
  char *xdg = getenv("XDG_CACHE_HOME") ? strdup(getenv("XDG_CACHE_HOME")) : NULL;
  setenv("GRADUS_CACHE_DIR", "/a/b", 1);
  CHECK(gr_kb_default_dir(d, sizeof d) == GR_OK && !strcmp(d, "/a/b/kb"), "%s", d);
  unsetenv("GRADUS_CACHE_DIR");
  setenv("XDG_CACHE_HOME", "/x", 1);
  CHECK(gr_kb_default_dir(d, sizeof d) == GR_OK && !strcmp(d, "/x/gradus/kb"), "%s", d);
  unsetenv("XDG_CACHE_HOME");
  setenv("HOME", "/home/u", 1);
  CHECK(gr_kb_default_dir(d, sizeof d) == GR_OK && !strcmp(d, "/home/u/.cache/gradus/kb"), "%s", d);
  CHECK(gr_kb_default_dir(d, 5) == GR_EARG, "too small a buffer");
  unsetenv("HOME");
  CHECK(gr_kb_default_dir(d, sizeof d) == GR_EARG, "nothing set");
  if (home) setenv("HOME", home, 1);
  if (gc) setenv("GRADUS_CACHE_DIR", gc, 1);
  if (xdg) setenv("XDG_CACHE_HOME", xdg, 1);
  free(home); free(gc); free(xdg);
}

TEST(put_get_roundtrip) {
  char *root = tmpdir();
  char dir[4096];
  snprintf(dir, sizeof dir, "%s/deep/er/kb", root); /* parents created */
  gr_err e;
  gr_kb *kb = gr_kb_open(dir, &e);
  CHECK(kb != NULL, "%s", e.msg);
  if (!kb) { rm_rf(root); free(root); return; }
  gr_template *t = make_template(5, 3, 1), *u = NULL;
  char w[512];
  CHECK(gr_kb_get(kb, t->key, &u, w, sizeof w, &e) == GR_OK && !u && !w[0], "absent: no warning");
  CHECK(gr_kb_get(kb, "../../etc/passwd", &u, w, sizeof w, &e) == GR_EARG, "bad key refused");
  CHECK(gr_kb_put(kb, t, &e) == GR_OK, "%s", e.msg);
  CHECK(gr_kb_get(kb, t->key, &u, w, sizeof w, &e) == GR_OK && u && !w[0], "present: %s", w);
  CHECK(u && same_template(t, u), "round trip through the store");
  gr_template_free(u);
  /* created 0 is stamped with the current time */
  gr_template *t2 = make_template(6, 1, 0);
  t2->created = 0;
  long long before = (long long)time(NULL);
  CHECK(gr_kb_put(kb, t2, &e) == GR_OK, "%s", e.msg);
  gr_kb_get(kb, t2->key, &u, w, sizeof w, &e);
  CHECK(u && u->created >= before && u->created <= (long long)time(NULL) + 1, "created stamped");
  gr_template_free(u);
  /* put again replaces, list has two entries in key order */
  t->qualified = 0;
  t->quality[0] = 42;
  CHECK(gr_kb_put(kb, t, &e) == GR_OK, "%s", e.msg);
  gr_kb_entry *v;
  size_t n;
  CHECK(gr_kb_list(kb, &v, &n, w, sizeof w, &e) == GR_OK && n == 2, "n = %zu", n);
  if (n == 2) {
    CHECK(strcmp(v[0].key, v[1].key) < 0, "sorted");
    const gr_kb_entry *x = !strcmp(v[0].key, t->key) ? &v[0] : &v[1];
    CHECK(!strcmp(x->signature, t->signature), "signature with quotes, UTF-8 and newline kept");
    CHECK(x->quality[0] == 42 && isnan(x->quality[3]) && isinf(x->quality[5]), "quality");
    CHECK(x->qualified == 0 && x->created == t->created, "qualified, created");
    char p[4200];
    blob_file(p, sizeof p, dir, t->key);
    struct stat st;
    CHECK(stat(p, &st) == 0 && (size_t)st.st_size == x->bytes, "bytes = file size");
  }
  gr_kb_entries_free(v, n);
  CHECK(count_temps(dir) == 0, "no temporaries left");
  gr_kb_report r;
  CHECK(gr_kb_verify(kb, &r, &e) == GR_OK && r.ok == 2 && r.corrupt == 0 && r.index_ok, "verify");
  gr_kb_report_clear(&r);
  gr_template_free(t);
  gr_template_free(t2);
  gr_kb_close(kb);
  gr_kb_close(NULL);
  /* a file where the directory should be */
  char f[4200];
  snprintf(f, sizeof f, "%s/plain", root);
  write_file(f, "x", 1);
  CHECK(gr_kb_open(f, &e) == NULL && e.code == GR_EIO, "%s", e.msg);
  rm_rf(root);
  free(root);
}

/* Damage the blob of `key` in one of several ways. */
static void damage(const char *dir, const char *key, int how, const char *other_key) {
  char p[4200], q[4200];
  blob_file(p, sizeof p, dir, key);
  size_t n;
  unsigned char *b = read_file(p, &n);
  if (!b) return;
  switch (how) {
    case 0: b[n / 2] ^= 0x01; write_file(p, b, n); break;  /* flip a byte */
    case 1: write_file(p, b, n - 9); break;                 /* truncate */
    case 2: b[0] = 'X'; write_file(p, b, n); break;         /* wrong magic */
    case 3:                                                 /* another template's blob */
      blob_file(q, sizeof q, dir, other_key);
      free(b);
      b = read_file(q, &n);
      write_file(p, b, n);
      break;
    case 4: write_file(p, "hello, not a template\n", 22); break; /* foreign file */
    case 5: write_file(p, "", 0); break;                    /* empty */
  }
  free(b);
}

TEST(corrupt_blobs_detected) {
  char *dir = tmpdir();
  gr_err e;
  gr_kb *kb = gr_kb_open(dir, &e);
  enum { N = 6 };
  gr_template *t[N + 1];
  for (int i = 0; i <= N; i++) {
    t[i] = make_template(20 + i, 2, i % 2);
    CHECK(gr_kb_put(kb, t[i], &e) == GR_OK, "%s", e.msg);
  }
  for (int i = 0; i < N; i++) damage(dir, t[i]->key, i, t[N]->key);
  char w[1024];
  for (int i = 0; i < N; i++) {
    gr_template *u = (gr_template *)1;
    int rc = gr_kb_get(kb, t[i]->key, &u, w, sizeof w, &e);
    CHECK(rc == GR_OK && u == NULL && strstr(w, "damaged") && strstr(w, t[i]->key),
          "damage %d: rc %d, warning '%s'", i, rc, w);
  }
  gr_template *u = NULL;
  CHECK(gr_kb_get(kb, t[N]->key, &u, w, sizeof w, &e) == GR_OK && u && !w[0], "intact one still read");
  gr_template_free(u);
  /* list: the index no longer matches the files, so it is rebuilt without
   * the damaged ones, with a warning naming them */
  gr_kb_entry *v;
  size_t n;
  CHECK(gr_kb_list(kb, &v, &n, w, sizeof w, &e) == GR_OK, "%s", e.msg);
  CHECK(n == 1 && !strcmp(v[0].key, t[N]->key), "only the intact one listed, n = %zu", n);
  CHECK(strstr(w, "damaged"), "warning: %s", w);
  gr_kb_entries_free(v, n);
  gr_kb_report r;
  CHECK(gr_kb_verify(kb, &r, &e) == GR_OK, "%s", e.msg);
  CHECK(r.ok == 1 && r.corrupt == N, "verify: ok %zu corrupt %zu", r.ok, r.corrupt);
  CHECK(r.messages && strstr(r.messages, "checksum") && strstr(r.messages, "magic"), "%s", r.messages);
  gr_kb_report_clear(&r);
  /* the caller rebuilds and overwrites */
  CHECK(gr_kb_put(kb, t[0], &e) == GR_OK, "%s", e.msg);
  CHECK(gr_kb_get(kb, t[0]->key, &u, w, sizeof w, &e) == GR_OK && u && same_template(u, t[0]), "rebuilt");
  gr_template_free(u);
  for (int i = 0; i <= N; i++) gr_template_free(t[i]);
  gr_kb_close(kb);
  rm_rf(dir);
  free(dir);
}

TEST(index_rebuilt) {
  char *dir = tmpdir();
  gr_err e;
  gr_kb *kb = gr_kb_open(dir, &e);
  gr_template *t[3];
  for (int i = 0; i < 3; i++) {
    t[i] = make_template(40 + i, 1, 0);
    gr_kb_put(kb, t[i], &e);
  }
  char idx[4200];
  snprintf(idx, sizeof idx, "%s/index.yaml", dir);
  for (int how = 0; how < 3; how++) {
    if (how == 0) unlink(idx);                                  /* deleted */
    if (how == 1) write_file(idx, "format: 1\ntemplates: [oops\n", 27); /* garbage */
    if (how == 2) { /* truncated in the middle of an entry */
      size_t n;
      unsigned char *b = read_file(idx, &n);
      write_file(idx, b, n / 2);
      free(b);
    }
    gr_kb_report r;
    gr_kb_verify(kb, &r, &e);
    CHECK(!r.index_ok && r.ok == 3, "verify notices the index (case %d)", how);
    gr_kb_report_clear(&r);
    gr_kb_entry *v;
    size_t n;
    char w[256];
    CHECK(gr_kb_list(kb, &v, &n, w, sizeof w, &e) == GR_OK && n == 3 && !w[0], "case %d: n %zu", how, n);
    int found = 0;
    for (size_t i = 0; i < n; i++)
      for (int k = 0; k < 3; k++)
        found += !strcmp(v[i].key, t[k]->key) && !strcmp(v[i].signature, t[k]->signature) &&
                 v[i].created == t[k]->created && v[i].qualified == t[k]->qualified &&
                 v[i].quality[1] == t[k]->quality[1];
    CHECK(found == 3, "entries rebuilt from the blobs (case %d)", how);
    gr_kb_entries_free(v, n);
    CHECK(file_exists(idx), "index rewritten");
    gr_kb_verify(kb, &r, &e);
    CHECK(r.index_ok && r.index_entries == 3, "index consistent again (case %d)", how);
    gr_kb_report_clear(&r);
  }
  /* a put on top of a damaged index rebuilds it too */
  write_file(idx, "nonsense", 8);
  gr_template *t3 = make_template(43, 1, 0);
  CHECK(gr_kb_put(kb, t3, &e) == GR_OK, "%s", e.msg);
  gr_kb_report r;
  gr_kb_verify(kb, &r, &e);
  CHECK(r.index_ok && r.index_entries == 4, "index after put: %zu entries", r.index_entries);
  gr_kb_report_clear(&r);
  gr_template_free(t3);
  for (int i = 0; i < 3; i++) gr_template_free(t[i]);
  gr_kb_close(kb);
  rm_rf(dir);
  free(dir);
}

TEST(two_processes) {
  char *dir = tmpdir();
  enum { PER = 50 };
  pid_t pid[2];
  for (int c = 0; c < 2; c++) {
    pid[c] = fork();
    if (pid[c] == 0) {
      gr_err e;
      gr_kb *kb = gr_kb_open(dir, &e);
      int bad = !kb;
      for (int i = 0; i < PER && kb; i++) {
        gr_template *t = make_template(1000 * (c + 1) + i, 2, i % 2);
        bad += gr_kb_put(kb, t, &e) != GR_OK;
        gr_template_free(t);
      }
      gr_kb_close(kb);
      _exit(bad ? 1 : 0);
    }
  }
  int ok = 1;
  for (int c = 0; c < 2; c++) {
    int st = 0;
    waitpid(pid[c], &st, 0);
    ok &= WIFEXITED(st) && WEXITSTATUS(st) == 0;
  }
  CHECK(ok, "both writers succeeded");
  gr_err e;
  gr_kb *kb = gr_kb_open(dir, &e);
  gr_kb_report r;
  CHECK(gr_kb_verify(kb, &r, &e) == GR_OK, "%s", e.msg);
  CHECK(r.ok == 2 * PER && r.corrupt == 0 && r.orphans == 0, "ok %zu corrupt %zu orphans %zu", r.ok,
        r.corrupt, r.orphans);
  CHECK(r.index_ok && r.index_entries == 2 * PER, "index has all %d: %zu (ok %d)", 2 * PER,
        r.index_entries, r.index_ok);
  gr_kb_report_clear(&r);
  int all = 1;
  for (int c = 0; c < 2; c++)
    for (int i = 0; i < PER; i++) {
      gr_template *t = make_template(1000 * (c + 1) + i, 2, i % 2), *u = NULL;
      char w[256];
      gr_kb_get(kb, t->key, &u, w, sizeof w, &e);
      all &= u && same_template(t, u);
      gr_template_free(t);
      gr_template_free(u);
    }
  CHECK(all, "every template readable and identical");
  CHECK(count_temps(dir) == 0, "no temporaries left");
  gr_kb_close(kb);
  rm_rf(dir);
  free(dir);
}

typedef struct thr {
  gr_kb *kb;
  int id, bad;
} thr;

static void *thr_run(void *arg) {
  thr *a = arg;
  gr_err e;
  for (int i = 0; i < 20; i++) {
    gr_template *t = make_template(3000 + 100 * a->id + i, 1, 0), *u = NULL;
    char w[256];
    if (gr_kb_put(a->kb, t, &e) != GR_OK) a->bad++;
    gr_template *s = make_template(2000 + i % 5, 2, 1); /* shared, read by all */
    if (gr_kb_get(a->kb, s->key, &u, w, sizeof w, &e) != GR_OK || !u || !same_template(s, u)) a->bad++;
    gr_template_free(u);
    gr_template_free(s);
    gr_template_free(t);
  }
  return NULL;
}

TEST(threads) {
  char *dir = tmpdir();
  gr_err e;
  gr_kb *kb = gr_kb_open(dir, &e);
  for (int i = 0; i < 5; i++) {
    gr_template *s = make_template(2000 + i, 2, 1);
    gr_kb_put(kb, s, &e);
    gr_template_free(s);
  }
  pthread_t th[4];
  thr a[4];
  for (int i = 0; i < 4; i++) {
    a[i] = (thr){kb, i, 0};
    pthread_create(&th[i], NULL, thr_run, &a[i]);
  }
  int bad = 0;
  for (int i = 0; i < 4; i++) {
    pthread_join(th[i], NULL);
    bad += a[i].bad;
  }
  CHECK(bad == 0, "%d failures in threads", bad);
  gr_kb_report r;
  gr_kb_verify(kb, &r, &e);
  CHECK(r.ok == 85 && r.corrupt == 0 && r.index_ok && r.index_entries == 85, "ok %zu index %zu",
        r.ok, r.index_entries);
  gr_kb_report_clear(&r);
  gr_kb_close(kb);
  rm_rf(dir);
  free(dir);
}

TEST(prune) {
  char *dir = tmpdir();
  gr_err e;
  gr_kb *kb = gr_kb_open(dir, &e);
  gr_template *t[4];
  for (int i = 0; i < 4; i++) {
    t[i] = make_template(60 + i, 1, 0); /* created 1700000060 + i */
    gr_kb_put(kb, t[i], &e);
  }
  /* what a crash leaves: temporaries beside a blob and the index */
  char p[4200];
  snprintf(p, sizeof p, "%s/t/%s.gtp.tmp-Ab12Cd", dir, t[0]->key);
  write_file(p, "partial", 7);
  snprintf(p, sizeof p, "%s/index.yaml.tmp-zZ9yY8", dir);
  write_file(p, "format", 6);
  damage(dir, t[1]->key, 0, NULL);
  char other[4200];
  snprintf(other, sizeof other, "%s/t/README", dir); /* not ours: left alone */
  write_file(other, "x", 1);
  gr_kb_report r;
  gr_kb_verify(kb, &r, &e);
  CHECK(r.orphans == 2 && r.corrupt == 1 && r.ok == 3 && r.removed == 0, "verify sees them");
  gr_kb_report_clear(&r);
  CHECK(count_temps(dir) == 2, "verify removed nothing");
  CHECK(gr_kb_prune(kb, NULL, &r, &e) == GR_OK, "%s", e.msg);
  CHECK(r.orphans == 2 && r.corrupt == 1 && r.removed == 3 && r.ok == 3 && r.index_entries == 3,
        "orphans %zu corrupt %zu removed %zu ok %zu", r.orphans, r.corrupt, r.removed, r.ok);
  gr_kb_report_clear(&r);
  CHECK(count_temps(dir) == 0, "temporaries gone");
  blob_file(p, sizeof p, dir, t[1]->key);
  CHECK(!file_exists(p), "damaged blob gone");
  CHECK(file_exists(other), "foreign file kept");
  /* age limit: created before 1700000063 -> t[0], t[2] go, t[3] stays */
  gr_kb_prune_opts o = {1700000063, NULL, 0, 0};
  gr_kb_prune(kb, &o, &r, &e);
  CHECK(r.removed == 2 && r.ok == 1 && r.index_entries == 1, "age: removed %zu", r.removed);
  gr_kb_report_clear(&r);
  /* keep-set */
  for (int i = 0; i < 4; i++) gr_kb_put(kb, t[i], &e);
  const char *keep[2] = {t[1]->key, t[2]->key};
  gr_kb_prune_opts o2 = {0, keep, 2, 1};
  gr_kb_prune(kb, &o2, &r, &e);
  CHECK(r.removed == 2 && r.ok == 2, "keep-set: removed %zu", r.removed);
  gr_kb_report_clear(&r);
  gr_kb_entry *v;
  size_t n;
  char w[256];
  gr_kb_list(kb, &v, &n, w, sizeof w, &e);
  int k1 = 0, k2 = 0;
  for (size_t i = 0; i < n; i++) {
    k1 += !strcmp(v[i].key, t[1]->key);
    k2 += !strcmp(v[i].key, t[2]->key);
  }
  CHECK(n == 2 && k1 == 1 && k2 == 1, "exactly the keep-set listed");
  gr_kb_entries_free(v, n);
  gr_kb_verify(kb, &r, &e);
  CHECK(r.index_ok && r.corrupt == 0 && r.orphans == 0, "clean after prune");
  gr_kb_report_clear(&r);
  for (int i = 0; i < 4; i++) gr_template_free(t[i]);
  gr_kb_close(kb);
  rm_rf(dir);
  free(dir);
}

/* Templates built under an older engine geometry (grading rule) are never
 * asked for again: verify names them, prune removes them, others stay. */
TEST(stale_geometry) {
  char *dir = tmpdir();
  gr_err e;
  gr_kb *kb = gr_kb_open(dir, &e);
  const char *sig[3] = {"{gradus_template: 1, surface: primitive, L: 2}", GR_TEMPLATE_GEOMETRY " surface: primitive, L: 2}",
                        "{type: other}"};
  gr_template *t[3];
  for (int i = 0; i < 3; i++) {
    t[i] = gr_template_new(sig[i], 1, 1, 0, &e);
    CHECK(t[i] && gr_kb_put(kb, t[i], &e) == GR_OK, "%s", e.msg);
  }
  CHECK(gr_kb_stale(sig[0]) && !gr_kb_stale(sig[1]) && !gr_kb_stale(sig[2]), "stale: only the old geometry");
  gr_kb_report r;
  CHECK(gr_kb_verify(kb, &r, &e) == GR_OK, "%s", e.msg);
  CHECK(r.messages && strstr(r.messages, "stale") && strstr(r.messages, t[0]->key), "verify names it: %s",
        r.messages ? r.messages : "(none)");
  CHECK(r.corrupt == 0, "stale is not damage");
  gr_kb_report_clear(&r);
  CHECK(gr_kb_prune(kb, NULL, &r, &e) == GR_OK, "%s", e.msg);
  CHECK(r.removed == 1 && r.index_entries == 2, "removed %zu, left %zu", r.removed, r.index_entries);
  gr_kb_report_clear(&r);
  gr_template *got = NULL;
  CHECK(gr_kb_get(kb, t[0]->key, &got, NULL, 0, &e) == GR_OK && got == NULL, "stale template gone");
  CHECK(gr_kb_get(kb, t[1]->key, &got, NULL, 0, &e) == GR_OK && got != NULL, "current template kept");
  gr_template_free(got);
  for (int i = 0; i < 3; i++) gr_template_free(t[i]);
  gr_kb_close(kb);
  rm_rf(dir);
  free(dir);
}

/* An empty knowledge base in a new temporary directory (*dir, freed by
 * close_kb), or NULL after a failed CHECK. */
static gr_kb *fresh_kb(char **dir, gr_err *e) {
  *dir = tmpdir();
  gr_kb *kb = *dir ? gr_kb_open(*dir, e) : NULL;
  CHECK(kb != NULL, "%s", *dir ? e->msg : "no temporary directory");
  if (!kb && *dir) { rm_rf(*dir); free(*dir); }
  return kb;
}

static void close_kb(gr_kb *kb, char *dir) {
  gr_kb_close(kb);
  rm_rf(dir);
  free(dir);
}

/* gr_kb_put_many: a batch under one lock, each template got back whole and
 * listed once; a batch with a repeated key keeps the later one. */
TEST(put_many) {
  char *dir;
  gr_err e;
  gr_kb *kb = fresh_kb(&dir, &e);
  if (!kb) return;
  gr_template *t[4];
  for (int i = 0; i < 3; i++) t[i] = make_template(20 + i, 2, i % 2);
  t[3] = make_template(20, 2, 0);
  t[3]->quality[0] = 77; /* same key as t[0], put after it */
  CHECK(gr_kb_put_many(kb, (const gr_template *const *)t, 4, &e) == GR_OK, "%s", e.msg);
  CHECK(gr_kb_put_many(kb, NULL, 0, &e) == GR_OK, "an empty batch is nothing to do");
  gr_kb_entry *v;
  size_t n = 0;
  CHECK(gr_kb_list(kb, &v, &n, NULL, 0, &e) == GR_OK && n == 3, "3 keys listed, got %zu", n);
  for (size_t k = 0; k < n; k++)
    if (!strcmp(v[k].key, t[0]->key)) CHECK(v[k].quality[0] == 77, "the later of two puts listed");
  gr_kb_entries_free(v, n);
  for (int i = 1; i < 4; i++) {
    gr_template *u = NULL;
    CHECK(gr_kb_get(kb, t[i]->key, &u, NULL, 0, &e) == GR_OK && u && same_template(t[i], u), "template %d back", i);
    gr_template_free(u);
  }
  CHECK(count_temps(dir) == 0, "no temporaries left");
  for (int i = 0; i < 4; i++) gr_template_free(t[i]);
  close_kb(kb, dir);
}

/* The writer thread: 30 records pushed back to back (more than its queue
 * of 8 holds) are all stored and counted; a writer whose
 * directory cannot take files reports the failure at a later push or at
 * finish, stores nothing after it and leaks nothing (ASan). */
TEST(writer_thread) {
  char *dir;
  gr_err e;
  gr_kb *kb = fresh_kb(&dir, &e);
  if (!kb) return;
  gr_kbw *w = gr_kbw_start(kb, &e);
  CHECK(w != NULL, "%s", e.msg);
  char keys[30][65];
  for (int i = 0; i < 30 && w; i++) {
    gr_template *t = make_template(100 + i, 3, 1);
    snprintf(keys[i], sizeof keys[i], "%s", t->key);
    CHECK(gr_kbw_push(w, t, &e) == GR_OK, "push %d: %s", i, e.msg);
  }
  long stored = -1;
  CHECK(gr_kbw_finish(w, &stored, &e) == GR_OK, "%s", e.msg);
  CHECK(stored == 30, "stored %ld of 30", stored);
  for (int i = 0; i < 30; i++) {
    gr_template *u = NULL, *t = make_template(100 + i, 3, 1);
    CHECK(gr_kb_get(kb, keys[i], &u, NULL, 0, &e) == GR_OK && u && same_template(t, u), "record %d stored", i);
    gr_template_free(u);
    gr_template_free(t);
  }
  gr_kb_entry *v;
  size_t n = 0;
  CHECK(gr_kb_list(kb, &v, &n, NULL, 0, &e) == GR_OK && n == 30, "index lists %zu", n);
  gr_kb_entries_free(v, n);
  /* failure: t/ replaced by a plain file (root ignores permissions) */
  char tp[4200];
  snprintf(tp, sizeof tp, "%s/t", dir);
  rm_rf(tp);
  FILE *f = fopen(tp, "w");
  if (f) fclose(f);
  w = gr_kbw_start(kb, &e);
  int failed_at = -1;
  for (int i = 0; i < 20 && w && failed_at < 0; i++)
    if (gr_kbw_push(w, make_template(200 + i, 1, 0), &e) != GR_OK) failed_at = i;
  if (failed_at >= 0) CHECK(e.code == GR_EIO && strstr(e.msg, "cannot write"), "push error: %s", e.msg);
  gr_err e2;
  stored = -1;
  int rc = gr_kbw_finish(w, &stored, &e2);
  CHECK(rc == GR_EIO && strstr(e2.msg, "cannot write"), "finish reports the failure: %d %s", rc, e2.msg);
  CHECK(stored == 0, "nothing stored after the failure, got %ld", stored);
  CHECK(gr_kbw_finish(NULL, NULL, &e2) == GR_OK, "no writer: nothing to finish");
  close_kb(kb, dir);
}

int main(void) {
  RUN(sha256_vectors);
  RUN(template_new_args);
  RUN(encode_decode_roundtrip);
  RUN(decode_rejects_damage);
  RUN(default_dir);
  RUN(put_get_roundtrip);
  RUN(corrupt_blobs_detected);
  RUN(index_rebuilt);
  RUN(two_processes);
  RUN(threads);
  RUN(prune);
  RUN(stale_geometry);
  RUN(put_many);
  RUN(writer_thread);
  DONE();
}
