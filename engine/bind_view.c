/* bind_view.c: Lua binding of the viewer's data (view.h, view_serve.h) and
 * of PNG reading (pngread.h).
 *   gradus.view.open(path) -> index       (errors: not a CLI file, truncated ...)
 *   index:info() -> {path, format, units, layers, bytes, dimension = {6}, z = {...}}
 *   index:layer(k [, quantum]) -> base64 text, {xmin, ymin, xmax, ymax}
 *   index:serve{page = html, port = 0, quantum = 1e-4, ready = function(port) end}
 *   index:close()
 *   gradus.view.png_read(path) -> width, height, RGBA bytes (rows top down) */
#include <stdlib.h>
#include <string.h>
#include "bind.h"
#include "pngread.h"
#include "view.h"
#include "view_serve.h"

#define MT_INDEX "gradus.viewindex"
#define DEFAULT_QUANTUM 1e-4 /* mm: 0.1 um */

typedef struct ud_index { gr_view_index *ix; } ud_index;

static gr_view_index *check_index(lua_State *L, int idx) {
  ud_index *u = luaL_checkudata(L, idx, MT_INDEX);
  luaL_argcheck(L, u->ix != NULL, idx, "the CLI index is closed");
  return u->ix;
}

static int ix_gc(lua_State *L) {
  ud_index *u = luaL_checkudata(L, 1, MT_INDEX);
  gr_view_index_free(u->ix);
  u->ix = NULL;
  return 0;
}

static int v_open(lua_State *L) {
  const char *path = luaL_checkstring(L, 1);
  ud_index *u = lua_newuserdatauv(L, sizeof *u, 0);
  u->ix = NULL;
  luaL_setmetatable(L, MT_INDEX);
  gr_err e;
  gr_err_clear(&e);
  u->ix = gr_view_index_open(path, &e);
  if (!u->ix) return gr_lua_error(L, &e);
  return 1;
}

static int ix_info(lua_State *L) {
  const gr_view_index *ix = check_index(L, 1);
  lua_createtable(L, 0, 7);
  lua_pushstring(L, ix->path);
  lua_setfield(L, -2, "path");
  lua_pushstring(L, ix->h.binary ? "binary" : "ascii");
  lua_setfield(L, -2, "format");
  lua_pushnumber(L, ix->h.units);
  lua_setfield(L, -2, "units");
  lua_pushinteger(L, (lua_Integer)ix->n);
  lua_setfield(L, -2, "layers");
  lua_pushinteger(L, (lua_Integer)ix->bytes);
  lua_setfield(L, -2, "bytes");
  lua_createtable(L, 6, 0);
  for (int a = 0; a < 6; a++) {
    lua_pushnumber(L, a < 3 ? ix->h.lo[a] : ix->h.hi[a - 3]);
    lua_rawseti(L, -2, a + 1);
  }
  lua_setfield(L, -2, "dimension");
  lua_createtable(L, (int)ix->n, 0);
  for (size_t k = 0; k < ix->n; k++) {
    lua_pushnumber(L, ix->layer[k].z);
    lua_rawseti(L, -2, (lua_Integer)k + 1);
  }
  lua_setfield(L, -2, "z");
  return 1;
}

typedef struct enc { gr_view_buf b; double quantum, lo[2], hi[2]; } enc;

static int encode_one(void *ud, const gr_layer *l, gr_err *e) {
  enc *x = ud;
  gr_layer_bounds(l, x->lo, x->hi);
  return gr_view_encode(l, x->quantum, &x->b, e);
}

static double check_quantum(lua_State *L, int idx) {
  double q = luaL_optnumber(L, idx, DEFAULT_QUANTUM);
  luaL_argcheck(L, q > 0 && q < 1e3, idx, lua_pushfstring(L, "quantum must be > 0 mm, got %f", q));
  return q;
}

static int ix_layer(lua_State *L) {
  const gr_view_index *ix = check_index(L, 1);
  lua_Integer k = luaL_checkinteger(L, 2);
  double q = check_quantum(L, 3);
  if (k < 1 || (size_t)k > ix->n)
    return luaL_error(L, "layer %d is out of range: %s has %d layers", (int)k, ix->path, (int)ix->n);
  enc x = {{NULL, 0, 0}, q, {0, 0}, {0, 0}};
  gr_err e;
  gr_err_clear(&e);
  int rc = gr_view_layer(ix, (size_t)k - 1, encode_one, &x, &e);
  size_t n = 0;
  char *s = rc ? NULL : gr_view_base64(x.b.p, x.b.n, &n);
  free(x.b.p);
  if (rc) return gr_lua_error(L, &e);
  if (!s) return luaL_error(L, "out of memory");
  lua_pushlstring(L, s, n);
  free(s);
  lua_createtable(L, 4, 0);
  double bb[4] = {x.lo[0], x.lo[1], x.hi[0], x.hi[1]};
  for (int i = 0; i < 4; i++) {
    lua_pushnumber(L, bb[i]);
    lua_rawseti(L, -2, i + 1);
  }
  return 2;
}

/* ready callback: calls the Lua function at stack index 3 with the port */
static int on_ready(void *ud, int port, gr_err *e) {
  lua_State *L = ud;
  if (lua_isnil(L, 3)) return GR_OK;
  lua_pushvalue(L, 3);
  lua_pushinteger(L, port);
  if (lua_pcall(L, 1, 0, 0) == LUA_OK) return GR_OK;
  gr_fail(e, GR_EARG, "%s", lua_tostring(L, -1));
  lua_pop(L, 1);
  return GR_EARG;
}

static int ix_serve(lua_State *L) {
  const gr_view_index *ix = check_index(L, 1);
  luaL_checktype(L, 2, LUA_TTABLE);
  lua_settop(L, 2);
  lua_getfield(L, 2, "ready"); /* index 3 */
  luaL_argcheck(L, lua_isnil(L, 3) || lua_isfunction(L, 3), 2, "ready must be a function");
  lua_getfield(L, 2, "page"); /* index 4: kept here, alive while serving */
  size_t plen;
  const char *page = lua_tolstring(L, 4, &plen);
  luaL_argcheck(L, page != NULL, 2, "page (the HTML text) is required");
  lua_Integer port = gr_opt_integer(L, 2, "port", 0);
  luaL_argcheck(L, port >= 0 && port <= 65535, 2, lua_pushfstring(L, "port must be 0..65535, got %d", (int)port));
  gr_view_serve_opts o = {(int)port, page, plen, gr_opt_number(L, 2, "quantum", DEFAULT_QUANTUM), on_ready, L};
  gr_err e;
  gr_err_clear(&e);
  if (gr_view_serve(ix, &o, &e)) return gr_lua_error(L, &e);
  return 0;
}

static int v_png_read(lua_State *L) {
  const char *path = luaL_checkstring(L, 1);
  unsigned char *p;
  int w, h;
  gr_err e;
  gr_err_clear(&e);
  if (gr_pngread(path, &p, &w, &h, &e)) return gr_lua_error(L, &e);
  lua_pushinteger(L, w);
  lua_pushinteger(L, h);
  lua_pushlstring(L, (const char *)p, (size_t)w * (size_t)h * 4);
  free(p);
  return 3;
}

static const luaL_Reg ix_methods[] = {
    {"info", ix_info}, {"layer", ix_layer}, {"serve", ix_serve}, {"close", ix_gc}, {NULL, NULL}};
static const luaL_Reg view_fns[] = {{"open", v_open}, {"png_read", v_png_read}, {NULL, NULL}};

int gr_open_view(lua_State *L) {
  luaL_newmetatable(L, MT_INDEX);
  luaL_newlib(L, ix_methods);
  lua_setfield(L, -2, "__index");
  lua_pushcfunction(L, ix_gc);
  lua_setfield(L, -2, "__gc");
  lua_pushcfunction(L, ix_gc);
  lua_setfield(L, -2, "__close");
  lua_pop(L, 1);
  luaL_newlib(L, view_fns);
  lua_setfield(L, -2, "view");
  return 0;
}
