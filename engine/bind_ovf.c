/* bind_ovf.c: Lua binding of machine files beyond writing CLI:
 *   gradus.info(path) -> what a CLI or OVF file holds (also gradus.cli.info)
 *   gradus.convert(in, out [, {format = "ascii"|"binary"|"ovf"}]) -> out
 *   gradus.ovf.plane(path, i) -> layer, {style per block}: work plane i
 *       (1-based) through the LUTs
 * and the OVF writer of job:run (gr_lua_ovf_open). */
#include <string.h>
#include "bind.h"
#include "bind_ovf.h"
#include "place.h"
#include "convert.h"
#include <stdlib.h>

static const char *const KINDS[GR_NKINDS] = {"contour", "hatch", "edge"};

static void set_str(lua_State *L, const char *k, const char *v) { lua_pushstring(L, v); lua_setfield(L, -2, k); }

/* ---- the OVF writer of job:run ---- */
/* opts.styles = {{id=, label=, power=, speed=, jump_speed=}, ...} (the
 * manifest's build styles), opts.name, opts.jump_delay, opts.polygon_delay (s). */
gr_ovf_writer *gr_lua_ovf_open(lua_State *L, int opts, const char *path, const gr_job_opts *o, int layers, gr_err *e) {
  /* scratch for the styles (gr_ovf_open copies them), collected with the stack */
  gr_cli_style *sty = lua_newuserdatauv(L, GR_CLI_MAXSTYLES * sizeof *sty, 0);
  gr_ovf_job j;
  memset(&j, 0, sizeof j);
  lua_getfield(L, opts, "styles");
  int n = lua_istable(L, -1) ? (int)luaL_len(L, -1) : 0;
  if (n > GR_CLI_MAXSTYLES) luaL_error(L, "bad option 'styles' (at most %d build styles)", GR_CLI_MAXSTYLES);
  for (int i = 0; i < n; i++) {
    lua_geti(L, -1, i + 1);
    int t = lua_gettop(L);
    gr_cli_style *s = &sty[i];
    s->id = gr_opt_integer(L, t, "id", i + 1);
    s->power = gr_opt_number(L, t, "power", NAN);
    s->speed = gr_opt_number(L, t, "speed", NAN);
    s->focus = gr_opt_number(L, t, "focus", NAN);
    s->jump_speed = gr_opt_number(L, t, "jump_speed", NAN);
    snprintf(s->name, sizeof s->name, "%s", gr_opt_string(L, t, "label", ""));
    lua_pop(L, 1);
  }
  lua_pop(L, 1);
  j.name = gr_opt_string(L, opts, "name", "gradus");
  j.nstyles = n;
  j.style = sty;
  j.jump_delay = gr_opt_number(L, opts, "jump_delay", 0);
  j.polygon_delay = gr_opt_number(L, opts, "polygon_delay", 0);
  j.hatch = o->hatch;
  j.angle = o->angle;
  j.rotation = o->rotation;
  j.layer = o->layer;
  j.beam_offset = o->beam_offset;
  j.contours = o->contours;
  j.pattern = o->pattern;
  j.layers = layers;
  gr_ovf_writer *w = gr_ovf_open(path, &j, e);
  lua_pop(L, 1); /* the scratch */
  return w;
}

/* ---- info ---- */
typedef struct infoctx {
  long layers, empty;
  double lo[2], hi[2], zmin, zmax;
  long blocks[GR_CLI_MAXSTYLES], vectors[GR_CLI_MAXSTYLES];
  double length[GR_CLI_MAXSTYLES];
  int laser[GR_CLI_MAXSTYLES], kind[GR_CLI_MAXSTYLES];
  long lblocks[GR_MAX_LASERS + 1], lvectors[GR_MAX_LASERS + 1]; /* per laser (the last: beyond) */
  double llength[GR_MAX_LASERS + 1];
  int nlasers;
} infoctx;

static long block_vectors(const gr_block *b) { return b->shape == GR_SEGMENTS ? (long)b->n / 2 : b->n > 0 ? (long)b->n - 1 : 0; }

static int info_layer(void *ud, const gr_layer *l, const int *style, const gr_cli_header *h, gr_err *e) {
  (void)e;
  (void)h;
  infoctx *c = ud;
  c->layers++;
  c->zmin = fmin(c->zmin, l->z);
  c->zmax = fmax(c->zmax, l->z);
  if (l->nb == 0) c->empty++;
  for (size_t b = 0; b < l->nb; b++) {
    const gr_block *bk = &l->b[b];
    int s = style[b], la = bk->laser < GR_MAX_LASERS ? bk->laser : GR_MAX_LASERS;
    double len = gr_block_length(l, bk);
    c->blocks[s]++;
    c->vectors[s] += block_vectors(bk);
    c->length[s] += len;
    c->laser[s] = bk->laser;
    c->kind[s] = bk->kind;
    c->lblocks[la]++;
    c->lvectors[la] += block_vectors(bk);
    c->llength[la] += len;
    if (la + 1 > c->nlasers) c->nlasers = la + 1;
    for (size_t q = 0; q < bk->n; q++) {
      double x = l->xy[2 * (bk->start + q)], y = l->xy[2 * (bk->start + q) + 1];
      c->lo[0] = fmin(c->lo[0], x); c->hi[0] = fmax(c->hi[0], x);
      c->lo[1] = fmin(c->lo[1], y); c->hi[1] = fmax(c->hi[1], y);
    }
  }
  return GR_OK;
}

static void push_style(lua_State *L, const gr_cli_style *s, const infoctx *c, int i) {
  lua_newtable(L);
  gr_lua_setint(L, "id", s->id);
  set_str(L, "label", s->name);
  gr_lua_setint(L, "laser", c->laser[i] + 1);
  set_str(L, "kind", KINDS[c->kind[i] >= 0 && c->kind[i] < GR_NKINDS ? c->kind[i] : GR_EDGE]);
  if (!isnan(s->power)) gr_lua_setnum(L, "power", s->power);
  if (!isnan(s->speed)) gr_lua_setnum(L, "speed", s->speed);
  if (!isnan(s->focus)) gr_lua_setnum(L, "focus", s->focus);
  if (!isnan(s->jump_speed)) gr_lua_setnum(L, "jump_speed", s->jump_speed);
  gr_lua_setint(L, "blocks", c->blocks[i]);
  gr_lua_setint(L, "vectors", c->vectors[i]);
  gr_lua_setnum(L, "length_mm", c->length[i]);
}

static void push_info(lua_State *L, const char *path, const gr_cli_header *h, const infoctx *c) {
  lua_newtable(L);
  set_str(L, "file", path);
  set_str(L, "format", h->ovf ? "ovf" : !h->binary ? "ascii" : h->short_cmds ? "binary-short" : "binary");
  gr_lua_setnum(L, "units", h->units);
  gr_lua_setint(L, "layers", c->layers);
  gr_lua_setint(L, "layers_declared", h->layers);
  gr_lua_setint(L, "empty_layers", c->empty);
  lua_newtable(L);
  for (int a = 0; a < 6; a++) {
    lua_pushnumber(L, a < 3 ? h->lo[a] : h->hi[a - 3]);
    lua_rawseti(L, -2, a + 1);
  }
  lua_setfield(L, -2, "dimension");
  if (c->layers > 0) {
    double v[6] = {c->lo[0], c->lo[1], c->zmin, c->hi[0], c->hi[1], c->zmax};
    lua_newtable(L);
    for (int a = 0; a < 6; a++) { lua_pushnumber(L, isfinite(v[a]) ? v[a] : 0); lua_rawseti(L, -2, a + 1); }
    lua_setfield(L, -2, "bounds");
    lua_newtable(L);
    gr_lua_setnum(L, "min", c->zmin);
    gr_lua_setnum(L, "max", c->zmax);
    lua_setfield(L, -2, "z");
  }
  if (h->nlabels) {
    lua_newtable(L);
    for (int i = 0; i < h->nlabels; i++) {
      lua_pushstring(L, h->label[i].text);
      lua_rawseti(L, -2, h->label[i].id);
    }
    lua_setfield(L, -2, "labels");
  }
  lua_newtable(L);
  double total = 0;
  for (int i = 0; i < h->nstyles; i++) {
    if (!c->blocks[i]) continue;
    push_style(L, &h->style[i], c, i);
    lua_rawseti(L, -2, (lua_Integer)luaL_len(L, -2) + 1);
    total += c->length[i];
  }
  lua_setfield(L, -2, "styles");
  lua_newtable(L);
  for (int la = 0; la < c->nlasers; la++) {
    lua_newtable(L);
    gr_lua_setint(L, "laser", la + 1);
    gr_lua_setint(L, "blocks", c->lblocks[la]);
    gr_lua_setint(L, "vectors", c->lvectors[la]);
    gr_lua_setnum(L, "length_mm", c->llength[la]);
    lua_rawseti(L, -2, la + 1);
  }
  lua_setfield(L, -2, "lasers");
  gr_lua_setnum(L, "length_mm", total);
}

int gr_l_info(lua_State *L) {
  const char *path = luaL_checkstring(L, 1);
  gr_lua_guard(L, path, "r");
  infoctx *c = lua_newuserdatauv(L, sizeof *c, 0);
  gr_cli_header *h = lua_newuserdatauv(L, sizeof *h, 0);
  memset(c, 0, sizeof *c);
  c->lo[0] = c->lo[1] = c->zmin = INFINITY;
  c->hi[0] = c->hi[1] = c->zmax = -INFINITY;
  gr_err e;
  gr_err_clear(&e);
  if (gr_cli_read_ex(path, h, info_layer, c, &e)) return gr_lua_error(L, &e);
  push_info(L, path, h, c);
  return 1;
}

/* gradus.convert(in, out [, {format=}]) -> out */
static int l_convert(lua_State *L) {
  const char *in = luaL_checkstring(L, 1), *out = luaL_checkstring(L, 2);
  gr_lua_guard(L, in, "r");
  gr_lua_guard(L, out, "w");
  const char *name = gr_opt_string(L, 3, "format", NULL);
  int fmt;
  gr_err e;
  gr_err_clear(&e);
  if (gr_convert_format(name, out, &fmt, &e) || gr_convert(in, out, fmt, &e)) return gr_lua_error(L, &e);
  lua_pushstring(L, out);
  return 1;
}

/* gradus.ovf.plane(path, i) -> layer, styles: work plane i (1-based) read
 * through the LUTs; styles[b] = {key=, name=, power=, speed=} of block b. */
static int l_plane(lua_State *L) {
  const char *path = luaL_checkstring(L, 1);
  gr_lua_guard(L, path, "r");
  lua_Integer i = luaL_checkinteger(L, 2);
  gr_cli_header *h = lua_newuserdatauv(L, sizeof *h, 0);
  gr_err e;
  gr_err_clear(&e);
  gr_ovf_file *f = gr_ovf_open_read(path, &e);
  if (!f) return gr_lua_error(L, &e);
  gr_ovf_header(f, h);
  gr_layer *l = gr_layer_new(0);
  int *style = NULL;
  size_t cap = 0;
  int rc = l ? gr_ovf_read_plane(f, (int)i - 1, l, &style, &cap, h, &e) : gr_fail(&e, GR_EMEM, "out of memory");
  gr_ovf_free(f);
  if (rc) { free(style); gr_layer_free(l); return gr_lua_error(L, &e); }
  gr_push_layer(L, l);
  lua_createtable(L, (int)l->nb, 0);
  for (size_t b = 0; b < l->nb; b++) {
    const gr_cli_style *s = &h->style[style[b]];
    lua_createtable(L, 0, 4);
    gr_lua_setint(L, "key", s->id);
    set_str(L, "name", s->name);
    if (!isnan(s->power)) gr_lua_setnum(L, "power", s->power);
    if (!isnan(s->speed)) gr_lua_setnum(L, "speed", s->speed);
    lua_rawseti(L, -2, (lua_Integer)b + 1);
  }
  free(style);
  return 2;
}

static const luaL_Reg ovf_fns[] = {{"plane", l_plane}, {NULL, NULL}};

int gr_open_ovf(lua_State *L) {
  lua_pushcfunction(L, gr_l_info);
  lua_setfield(L, -2, "info");
  lua_pushcfunction(L, l_convert);
  lua_setfield(L, -2, "convert");
  luaL_newlib(L, ovf_fns);
  lua_setfield(L, -2, "ovf");
  return 0;
}
