/* bind_density.c: Lua binding of density tables and field files.
 *   gradus.density.table{surface=, level=0, kind="sheet"|"network", side=-1,
 *       ratio=1, cell=2, track=0.07, res=128, cache=dir, clamp=false} -> table
 *   t:rho(T) -> density; t:thickness(rho) -> T (mm); t:range() -> rho_lo,
 *   rho_hi, T_lo, T_hi; t:check(rho, x, y, z [, "porosity"]) raises when out
 *   of range; t:key(); t:extent() -> -min sd / L, max sd / L
 *   gradus.density.achieved(cli, {origin=, cell=, cells=, layer=, beam_offset=})
 *       -> {volume per voxel (mm^3), i + nx*(j + ny*k) + 1}
 *   gradus.field.file(path, {origin=, spacing=, pad=0}) -> field
 *   gradus.field.file_info(field) -> {n=, lo=, hi=} or nil */
#include <string.h>
#include "bind.h"
#include "density.h"
#include "fieldfile.h"

#define DT_MT "gradus.density_table"
typedef struct ldt { gr_dtable *t; } ldt;

gr_dtable *gr_test_dtable(lua_State *L, int idx) {
  ldt *b = luaL_testudata(L, idx, DT_MT);
  return b ? b->t : NULL;
}

static gr_dtable *check_dt(lua_State *L, int idx) {
  ldt *b = luaL_checkudata(L, idx, DT_MT);
  if (!b->t) luaL_argerror(L, idx, "density table is closed");
  return b->t;
}

static int dt_gc(lua_State *L) {
  ldt *b = luaL_checkudata(L, 1, DT_MT);
  gr_dtable_free(b->t);
  b->t = NULL;
  return 0;
}

static int l_table(lua_State *L) {
  luaL_checktype(L, 1, LUA_TTABLE);
  ldt *b = lua_newuserdatauv(L, sizeof *b, 0);
  b->t = NULL;
  luaL_setmetatable(L, DT_MT);
  gr_dtable_opts o = gr_dtable_defaults();
  o.surface = gr_opt_string(L, 1, "surface", o.surface);
  o.level = gr_opt_number(L, 1, "level", 0);
  const char *kind = gr_opt_string(L, 1, "kind", "sheet");
  if (strcmp(kind, "sheet") && strcmp(kind, "network"))
    return luaL_error(L, "bad option 'kind' (sheet or network, got '%s')", kind);
  o.kind = strcmp(kind, "sheet") ? GR_DENS_NETWORK : GR_DENS_SHEET;
  o.side = gr_opt_integer(L, 1, "side", -1);
  o.ratio = gr_opt_number(L, 1, "ratio", 1);
  o.cell = gr_opt_number(L, 1, "cell", o.cell);
  o.track = gr_opt_number(L, 1, "track", o.track);
  o.res = gr_opt_integer(L, 1, "res", o.res);
  o.cache = gr_opt_string(L, 1, "cache", NULL);
  o.clamp = gr_opt_boolean(L, 1, "clamp", 0);
  gr_err e;
  gr_err_clear(&e);
  if (!(b->t = gr_dtable_new(&o, &e))) return gr_lua_error(L, &e);
  return 1;
}

static int dt_rho(lua_State *L) {
  lua_pushnumber(L, gr_dtable_rho(check_dt(L, 1), luaL_checknumber(L, 2)));
  return 1;
}

static int dt_thickness(lua_State *L) {
  lua_pushnumber(L, gr_dtable_thickness(check_dt(L, 1), luaL_checknumber(L, 2)));
  return 1;
}

static int dt_range(lua_State *L) {
  double v[4];
  gr_dtable_range(check_dt(L, 1), &v[0], &v[1], &v[2], &v[3]);
  for (int k = 0; k < 4; k++) lua_pushnumber(L, v[k]);
  return 4;
}

static int dt_check(lua_State *L) {
  gr_dtable *t = check_dt(L, 1);
  double rho = luaL_checknumber(L, 2);
  double p[3] = {luaL_checknumber(L, 3), luaL_checknumber(L, 4), luaL_checknumber(L, 5)};
  gr_err e;
  gr_err_clear(&e);
  if (gr_dtable_check(t, rho, p, luaL_optstring(L, 6, "density"), &e)) return luaL_error(L, "%s", e.msg);
  return 0;
}

static int dt_key(lua_State *L) {
  lua_pushstring(L, gr_dtable_key(check_dt(L, 1)));
  return 1;
}

static int dt_extent(lua_State *L) {
  double lo, hi;
  gr_dtable_extent(check_dt(L, 1), &lo, &hi);
  lua_pushnumber(L, lo);
  lua_pushnumber(L, hi);
  return 2;
}

static int dt_tostring(lua_State *L) {
  gr_dtable *t = check_dt(L, 1);
  double v[4];
  gr_dtable_range(t, &v[0], &v[1], &v[2], &v[3]);
  lua_pushfstring(L, "density table (%s; reachable %f..%f)", gr_dtable_key(t), v[0], v[1]);
  return 1;
}

static int l_achieved(lua_State *L) {
  const char *path = luaL_checkstring(L, 1);
  luaL_checktype(L, 2, LUA_TTABLE);
  gr_achieved_opts o;
  memset(&o, 0, sizeof o);
  gr_opt_vec(L, 2, "origin", 3, o.origin);
  o.cell = gr_opt_number(L, 2, "cell", 0);
  double n[3] = {1, 1, 1};
  gr_opt_vec(L, 2, "cells", 3, n);
  for (int a = 0; a < 3; a++) {
    if (!(n[a] >= 1 && n[a] <= 100000 && n[a] == (int)n[a]))
      return luaL_error(L, "bad option 'cells' (whole numbers >= 1 expected, got %g)", n[a]);
    o.n[a] = (int)n[a];
  }
  o.layer = gr_opt_number(L, 2, "layer", 0);
  o.beam_offset = gr_opt_number(L, 2, "beam_offset", 0);
  size_t m = (size_t)o.n[0] * o.n[1] * o.n[2];
  double *vol = lua_newuserdatauv(L, m * sizeof *vol, 0); /* freed by the GC */
  gr_err e;
  gr_err_clear(&e);
  if (gr_density_achieved(path, &o, vol, &e)) return gr_lua_error(L, &e);
  lua_createtable(L, (int)m, 0);
  for (size_t i = 0; i < m; i++) {
    lua_pushnumber(L, vol[i]);
    lua_rawseti(L, -2, (lua_Integer)i + 1);
  }
  return 1;
}

static int l_file(lua_State *L) {
  const char *path = luaL_checkstring(L, 1);
  gr_fieldfile_opts o = gr_fieldfile_defaults();
  if (!lua_isnoneornil(L, 2)) {
    luaL_checktype(L, 2, LUA_TTABLE);
    gr_opt_vec(L, 2, "origin", 3, o.origin);
    gr_opt_vec(L, 2, "spacing", 3, o.spacing);
    o.pad = gr_opt_number(L, 2, "pad", 0);
  }
  gr_err e;
  gr_err_clear(&e);
  gr_field *f = gr_field_file(path, &o, &e);
  if (!f) return gr_lua_error(L, &e);
  gr_push_field(L, f);
  return 1;
}

static int l_file_info(lua_State *L) {
  gr_field *f = gr_check_field(L, 1);
  int n[3];
  double lo[3], hi[3];
  if (!gr_fieldfile_info(f, n, lo, hi)) return lua_pushnil(L), 1;
  lua_createtable(L, 0, 3);
  const char *names[3] = {"n", "lo", "hi"};
  for (int q = 0; q < 3; q++) {
    lua_createtable(L, 3, 0);
    for (int a = 0; a < 3; a++) {
      lua_pushnumber(L, q == 0 ? n[a] : (q == 1 ? lo[a] : hi[a]));
      lua_rawseti(L, -2, a + 1);
    }
    lua_setfield(L, -2, names[q]);
  }
  return 1;
}

int gr_open_density(lua_State *L) {
  static const luaL_Reg methods[] = {{"rho", dt_rho}, {"thickness", dt_thickness}, {"range", dt_range},
                                     {"check", dt_check}, {"key", dt_key}, {"extent", dt_extent}, {NULL, NULL}};
  luaL_newmetatable(L, DT_MT);
  lua_pushcfunction(L, dt_gc);
  lua_setfield(L, -2, "__gc");
  lua_pushcfunction(L, dt_gc);
  lua_setfield(L, -2, "__close");
  lua_pushcfunction(L, dt_tostring);
  lua_setfield(L, -2, "__tostring");
  luaL_newlib(L, methods);
  lua_setfield(L, -2, "__index");
  lua_pop(L, 1);
  static const luaL_Reg fns[] = {{"table", l_table}, {"achieved", l_achieved}, {NULL, NULL}};
  luaL_newlib(L, fns);
  lua_setfield(L, -2, "density");
  lua_getfield(L, -1, "field");
  if (lua_istable(L, -1)) {
    lua_pushcfunction(L, l_file);
    lua_setfield(L, -2, "file");
    lua_pushcfunction(L, l_file_info);
    lua_setfield(L, -2, "file_info");
  }
  lua_pop(L, 1);
  return 0;
}
