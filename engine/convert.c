/* convert.c: one machine file to another (CLI ASCII, CLI binary, OVF), see
 * convert.h. Two passes over the input: the first finds what the output's
 * header needs (layers, lasers, bounds, build styles), the second writes. */
#include "convert.h"
#include "ovf.h"
#include <stdlib.h>
#include <string.h>
#include <strings.h>

int gr_convert_format(const char *name, const char *path, int *fmt, gr_err *e) {
  if (name && *name) {
    if (!strcmp(name, "ascii")) *fmt = GR_FMT_ASCII;
    else if (!strcmp(name, "binary")) *fmt = GR_FMT_BINARY;
    else if (!strcmp(name, "ovf")) *fmt = GR_FMT_OVF;
    else return gr_fail(e, GR_EARG, "bad format '%s' (ascii, binary or ovf)", name);
    return GR_OK;
  }
  const char *dot = strrchr(path, '.');
  if (dot && !strcasecmp(dot, ".ovf")) *fmt = GR_FMT_OVF;
  else if (dot && !strcasecmp(dot, ".cli")) *fmt = GR_FMT_BINARY;
  else return gr_fail(e, GR_EARG, "%s: cannot tell the format from the extension (.cli or .ovf; or give the format)", path);
  return GR_OK;
}

typedef struct scan {
  int layers, maxlaser;
  double lo[3], hi[3];
} scan;

static int scan_layer(void *ud, const gr_layer *l, const int *style, const gr_cli_header *h, gr_err *e) {
  (void)style;
  (void)h;
  (void)e;
  scan *s = ud;
  s->layers++;
  s->lo[2] = fmin(s->lo[2], l->z);
  s->hi[2] = fmax(s->hi[2], l->z);
  for (size_t b = 0; b < l->nb; b++) {
    if (l->b[b].laser > s->maxlaser) s->maxlaser = l->b[b].laser;
    const double *p = l->xy + 2 * l->b[b].start;
    for (size_t q = 0; q < l->b[b].n; q++)
      for (int a = 0; a < 2; a++) {
        double v = p[2 * q + a];
        s->lo[a] = v < s->lo[a] ? v : s->lo[a]; /* not fmin: a libm call per coordinate */
        s->hi[a] = v > s->hi[a] ? v : s->hi[a];
      }
  }
  return GR_OK;
}

typedef struct sink {
  gr_cli_writer *cli;
  gr_ovf_writer *ovf;
  const int *keymap; /* style index -> marking_params_key */
  int *keys;
  size_t cap;
} sink;

static int write_layer(void *ud, const gr_layer *l, const int *style, const gr_cli_header *h, gr_err *e) {
  (void)h;
  sink *s = ud;
  if (s->cli) return gr_cli_write_layer(s->cli, l, e);
  if (gr_grow(&s->keys, &s->cap, l->nb + 1, sizeof *s->keys)) return gr_fail(e, GR_EMEM, "out of memory");
  for (size_t b = 0; b < l->nb; b++) s->keys[b] = s->keymap[style[b]];
  return gr_ovf_write_layer(s->ovf, l, s->keys, e);
}

/* Keys of the OVF marking parameter sets: the style ids when they are
 * distinct; else (a CLI whose parameter commands change under one id)
 * 1, 2, ... in the order met, so each combination keeps its values. */
static void key_map(gr_cli_header *h, int *keymap) {
  int unique = 1;
  for (int i = 0; i < h->nstyles; i++)
    for (int k = 0; k < i; k++) unique &= h->style[i].id != h->style[k].id;
  for (int i = 0; i < h->nstyles; i++) {
    keymap[i] = unique ? h->style[i].id : i + 1;
    h->style[i].id = keymap[i];
  }
}

int gr_convert(const char *in, const char *out, int fmt, gr_err *e) {
  gr_cli_header *h = malloc(sizeof *h);
  int *keymap = calloc(GR_CLI_MAXSTYLES, sizeof *keymap);
  if (!h || !keymap) { free(h); free(keymap); return gr_fail(e, GR_EMEM, "out of memory"); }
  scan sc = {0, 0, {INFINITY, INFINITY, INFINITY}, {-INFINITY, -INFINITY, -INFINITY}};
  int rc = gr_cli_read_ex(in, h, scan_layer, &sc, e);
  sink s = {NULL, NULL, keymap, NULL, 0};
  if (!rc && fmt == GR_FMT_OVF) {
    key_map(h, keymap);
    const char *base = strrchr(in, '/');
    gr_ovf_job j;
    memset(&j, 0, sizeof j);
    j.name = base ? base + 1 : in;
    j.nstyles = h->nstyles;
    j.style = h->style;
    j.layers = sc.layers;
    s.ovf = gr_ovf_open(out, &j, e);
    if (!s.ovf) rc = e->code;
  } else if (!rc) {
    gr_cli_header o = gr_cli_header_defaults();
    o.binary = fmt == GR_FMT_BINARY;
    if (!h->ovf) o.units = h->units;
    o.layers = sc.layers;
    o.nlasers = sc.maxlaser + 1;
    for (int a = 0; a < 3; a++) {
      o.lo[a] = sc.layers ? sc.lo[a] : 0;
      o.hi[a] = sc.layers ? sc.hi[a] : 0;
    }
    s.cli = gr_cli_open(out, &o, e);
    if (!s.cli) rc = e->code;
  }
  if (!rc) rc = gr_cli_read_ex(in, h, write_layer, &s, e);
  gr_err e2;
  gr_err_clear(&e2);
  int crc = s.cli ? gr_cli_close(s.cli, rc == GR_OK, &e2) : gr_ovf_close(s.ovf, rc == GR_OK, &e2);
  if (!rc && crc) { rc = crc; if (e) *e = e2; }
  free(s.keys);
  free(keymap);
  free(h);
  return rc;
}
