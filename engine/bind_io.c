/* bind_io.c: Lua binding of the output formats (CLI files).
 *   gradus.cli.read(path) -> {header = {...}, layers = {layer, ...}}
 *   gradus.cli.info(path) -> {format, units, layers, bounds, per id counts and lengths}
 * Layer pictures (SVG) and plots are drawn in Lua: lua/gradus/svg.lua. */
#include <math.h>
#include <string.h>
#include "bind.h"
#include "cli.h"
#include "raster.h"

static void push_header(lua_State *L, const gr_cli_header *h) {
  lua_newtable(L);
  lua_pushstring(L, h->binary ? "binary" : "ascii");
  lua_setfield(L, -2, "format");
  lua_pushnumber(L, h->units);
  lua_setfield(L, -2, "units");
  lua_pushinteger(L, h->layers);
  lua_setfield(L, -2, "layers_declared");
  lua_newtable(L);
  for (int a = 0; a < 6; a++) {
    lua_pushnumber(L, a < 3 ? h->lo[a] : h->hi[a - 3]);
    lua_rawseti(L, -2, a + 1);
  }
  lua_setfield(L, -2, "dimension");
}

typedef struct readctx { lua_State *L; int tbl; lua_Integer n; } readctx;

static int read_layer(void *ud, const gr_layer *l, gr_err *e) {
  readctx *c = ud;
  gr_layer *copy = gr_layer_new(l->z);
  if (!copy || gr_layer_append(copy, l, 0, 0)) { gr_layer_free(copy); return gr_fail(e, GR_EMEM, "out of memory"); }
  gr_push_layer(c->L, copy);
  lua_rawseti(c->L, c->tbl, ++c->n);
  return GR_OK;
}

static int l_read(lua_State *L) {
  const char *path = luaL_checkstring(L, 1);
  gr_lua_guard(L, path, "r");
  lua_newtable(L);
  readctx c = {L, lua_gettop(L), 0};
  gr_cli_header h;
  gr_err e;
  gr_err_clear(&e);
  if (gr_cli_read(path, &h, read_layer, &c, &e)) return gr_lua_error(L, &e);
  lua_newtable(L);
  push_header(L, &h);
  lua_setfield(L, -2, "header");
  lua_pushvalue(L, c.tbl);
  lua_setfield(L, -2, "layers");
  return 1;
}

typedef struct infoctx {
  long layers;
  double lo[2], hi[2], zmin, zmax;
  long ids[64];           /* blocks per id (1..63) */
  long vectors[64];
  double length[64];
  long empty;
} infoctx;

static int info_layer(void *ud, const gr_layer *l, gr_err *e) {
  (void)e;
  infoctx *c = ud;
  c->layers++;
  if (l->z < c->zmin) c->zmin = l->z;
  if (l->z > c->zmax) c->zmax = l->z;
  if (l->nb == 0) c->empty++;
  for (size_t b = 0; b < l->nb; b++) {
    const gr_block *bk = &l->b[b];
    int id = bk->laser * 3 + bk->kind + 1;
    if (id < 1 || id > 63) id = 63;
    c->ids[id]++;
    c->vectors[id] += bk->shape == GR_SEGMENTS ? (long)bk->n / 2 : (long)bk->n - 1;
    c->length[id] += gr_block_length(l, bk);
    for (size_t q = 0; q < bk->n; q++) {
      double x = l->xy[2 * (bk->start + q)], y = l->xy[2 * (bk->start + q) + 1];
      c->lo[0] = fmin(c->lo[0], x); c->hi[0] = fmax(c->hi[0], x);
      c->lo[1] = fmin(c->lo[1], y); c->hi[1] = fmax(c->hi[1], y);
    }
  }
  return GR_OK;
}

static int l_info(lua_State *L) {
  const char *path = luaL_checkstring(L, 1);
  gr_lua_guard(L, path, "r");
  infoctx c;
  memset(&c, 0, sizeof c);
  c.lo[0] = c.lo[1] = c.zmin = INFINITY;
  c.hi[0] = c.hi[1] = c.zmax = -INFINITY;
  gr_cli_header h;
  gr_err e;
  gr_err_clear(&e);
  if (gr_cli_read(path, &h, info_layer, &c, &e)) return gr_lua_error(L, &e);
  push_header(L, &h);
  lua_pushstring(L, path);
  lua_setfield(L, -2, "file");
  lua_pushinteger(L, c.layers);
  lua_setfield(L, -2, "layers");
  lua_pushinteger(L, c.empty);
  lua_setfield(L, -2, "empty_layers");
  if (c.layers > 0) {
    lua_newtable(L);
    double v[6] = {c.lo[0], c.lo[1], c.zmin, c.hi[0], c.hi[1], c.zmax};
    for (int a = 0; a < 6; a++) { lua_pushnumber(L, isfinite(v[a]) ? v[a] : 0); lua_rawseti(L, -2, a + 1); }
    lua_setfield(L, -2, "bounds");
  }
  lua_newtable(L);
  static const char *const kinds[3] = {"contour", "hatch", "edge"};
  double total = 0;
  for (int id = 1; id < 64; id++) {
    if (!c.ids[id]) continue;
    lua_newtable(L);
    lua_pushinteger(L, id);
    lua_setfield(L, -2, "id");
    lua_pushfstring(L, "laser%d-%s", (id - 1) / 3 + 1, kinds[(id - 1) % 3]);
    lua_setfield(L, -2, "label");
    lua_pushinteger(L, c.ids[id]);
    lua_setfield(L, -2, "blocks");
    lua_pushinteger(L, c.vectors[id]);
    lua_setfield(L, -2, "vectors");
    lua_pushnumber(L, c.length[id]);
    lua_setfield(L, -2, "length_mm");
    lua_rawseti(L, -2, (lua_Integer)luaL_len(L, -2) + 1);
    total += c.length[id];
  }
  lua_setfield(L, -2, "styles");
  lua_pushnumber(L, total);
  lua_setfield(L, -2, "length_mm");
  return 1;
}

/* gradus.png.layer(path, layer, {width=800, line_width=1.2, jumps=false}) */
static int l_png_layer(lua_State *L) {
  const char *path = luaL_checkstring(L, 1);
  gr_layer *l = gr_check_layer(L, 2);
  const char *dest = gr_lua_stage(L, path); /* the job's output transaction */
  gr_png_opts o = {gr_opt_integer(L, 3, "width", 800), gr_opt_number(L, 3, "line_width", 1.2),
                   gr_opt_boolean(L, 3, "jumps", 0)};
  gr_err e;
  gr_err_clear(&e);
  if (gr_png_layer(dest, l, &o, &e)) return gr_lua_error(L, &e);
  lua_pushstring(L, path);
  return 1;
}

static const luaL_Reg png_fns[] = {{"layer", l_png_layer}, {NULL, NULL}};

static const luaL_Reg cli_fns[] = {{"read", l_read}, {"info", l_info}, {NULL, NULL}};

int gr_open_io(lua_State *L) {
  luaL_newlib(L, cli_fns);
  lua_setfield(L, -2, "cli");
  luaL_newlib(L, png_fns);
  lua_setfield(L, -2, "png");
  return 0;
}
