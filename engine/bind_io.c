/* bind_io.c: Lua binding of the output formats (CLI files).
 *   gradus.cli.read(path) -> {header = {...}, layers = {layer, ...}}
 *   gradus.cli.info(path) -> what a CLI or OVF file holds (bind_ovf.c: gradus.info)
 * Layer pictures (SVG) and plots are drawn in Lua: lua/gradus/svg.lua. */
#include <math.h>
#include <string.h>
#include "bind.h"
#include "bind_ovf.h"
#include "cli.h"
#include "raster.h"

static void push_header(lua_State *L, const gr_cli_header *h) {
  lua_newtable(L);
  lua_pushstring(L, h->ovf ? "ovf" : h->binary ? "binary" : "ascii");
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

static const luaL_Reg cli_fns[] = {{"read", l_read}, {"info", gr_l_info}, {NULL, NULL}};

int gr_open_io(lua_State *L) {
  luaL_newlib(L, cli_fns);
  lua_setfield(L, -2, "cli");
  luaL_newlib(L, png_fns);
  lua_setfield(L, -2, "png");
  return 0;
}
