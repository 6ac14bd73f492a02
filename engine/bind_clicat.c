/* bind_clicat.c: gradus.cli.cat (clicat.h) and gradus.cli.plate (plate.h). */
#include "bind.h"
#include "clicat.h"
#include "cli.h"
#include "plate.h"
#include <math.h>
#include <stdlib.h>

/* gradus.cli.cat({part, ...}, out) -> {layers=, first=, last=, layer_mm=} */
static int l_cat(lua_State *L) {
  luaL_checktype(L, 1, LUA_TTABLE);
  const char *out = luaL_checkstring(L, 2);
  int n = (int)luaL_len(L, 1);
  luaL_argcheck(L, n >= 1, 1, "at least one part file expected");
  const char **parts = lua_newuserdatauv(L, (size_t)n * sizeof *parts, 0); /* freed by the GC */
  for (int i = 0; i < n; i++) {
    lua_geti(L, 1, i + 1);
    if (lua_type(L, -1) != LUA_TSTRING) return luaL_argerror(L, 1, "part file names (strings) expected");
    parts[i] = lua_tostring(L, -1);
    lua_pop(L, 1); /* the string stays alive in the table */
  }
  gr_clicat_info info;
  gr_err e;
  gr_err_clear(&e);
  if (gr_cli_cat(parts, n, out, &info, &e)) return gr_lua_error(L, &e);
  lua_createtable(L, 0, 4);
  gr_lua_setint(L, "layers", info.layers);
  gr_lua_setint(L, "first", info.first);
  gr_lua_setint(L, "last", info.last);
  gr_lua_setnum(L, "layer_mm", info.layer_mm);
  return 1;
}

/* ---- gradus.cli.plate (plate.h): several parts merged onto one plate ---- */
#define PLATE_MT "gradus.plate"

static gr_plate **check_plate(lua_State *L) {
  gr_plate **p = luaL_checkudata(L, 1, PLATE_MT);
  if (!*p) luaL_error(L, "plate is closed");
  return p;
}

static int l_plate_gc(lua_State *L) {
  gr_plate **p = luaL_checkudata(L, 1, PLATE_MT);
  gr_plate_free(*p);
  *p = NULL;
  return 0;
}

/* gradus.cli.plate() -> plate */
static int l_plate_new(lua_State *L) {
  gr_plate **p = lua_newuserdatauv(L, sizeof *p, 0); /* before the object it owns */
  *p = NULL;
  luaL_setmetatable(L, PLATE_MT);
  *p = gr_plate_new();
  if (!*p) return luaL_error(L, "out of memory");
  return 1;
}

static int part_index(lua_State *L, gr_plate *p, int idx) {
  lua_Integer i = luaL_checkinteger(L, idx);
  luaL_argcheck(L, i >= 1 && i <= gr_plate_count(p), idx, "no such part");
  return (int)i - 1;
}

/* plate:add(path, {name=, at={x, y}, rotation=deg}) -> part number */
static int l_plate_add(lua_State *L) {
  gr_plate *p = *check_plate(L);
  const char *path = luaL_checkstring(L, 2);
  luaL_checktype(L, 3, LUA_TTABLE);
  gr_lua_guard(L, path, "r");
  double at[2] = {0, 0};
  gr_opt_vec(L, 3, "at", 2, at);
  double rot = gr_opt_number(L, 3, "rotation", 0);
  const char *name = gr_opt_string(L, 3, "name", path);
  gr_err e;
  gr_err_clear(&e);
  if (gr_plate_add(p, path, name, at[0], at[1], rot, &e)) return gr_lua_error(L, &e);
  lua_pushinteger(L, gr_plate_count(p));
  return 1;
}

static void set_pair(lua_State *L, const char *key, double a, double b) {
  lua_createtable(L, 2, 0);
  lua_pushnumber(L, a);
  lua_rawseti(L, -2, 1);
  lua_pushnumber(L, b);
  lua_rawseti(L, -2, 2);
  lua_setfield(L, -2, key);
}

/* plate:part(i) -> {layers=, lasers=, zlo=, zhi=, centre={x,y}, lo={x,y}, hi={x,y}, length=} */
static int l_plate_part(lua_State *L) {
  gr_plate *p = *check_plate(L);
  gr_plate_part_info in;
  gr_plate_part(p, part_index(L, p, 2), &in);
  lua_createtable(L, 0, 8);
  gr_lua_setint(L, "layers", in.layers);
  gr_lua_setint(L, "lasers", in.lasers);
  gr_lua_setnum(L, "zlo", in.zlo);
  gr_lua_setnum(L, "zhi", in.zhi);
  gr_lua_setnum(L, "length", in.length);
  set_pair(L, "centre", in.centre[0], in.centre[1]);
  set_pair(L, "lo", in.lo[0], in.lo[1]);
  set_pair(L, "hi", in.hi[0], in.hi[1]);
  return 1;
}

/* plate:hull(i) -> {{x, y}, ...} counter-clockwise (mm) */
static int l_plate_hull(lua_State *L) {
  gr_plate *p = *check_plate(L);
  size_t n;
  const double *xy = gr_plate_hull(p, part_index(L, p, 2), &n);
  lua_createtable(L, (int)n, 0);
  for (size_t k = 0; k < n; k++) {
    lua_createtable(L, 2, 0);
    lua_pushnumber(L, xy[2 * k]);
    lua_rawseti(L, -2, 1);
    lua_pushnumber(L, xy[2 * k + 1]);
    lua_rawseti(L, -2, 2);
    lua_rawseti(L, -2, (lua_Integer)k + 1);
  }
  return 1;
}

/* plate:overlap(i, j [, tol=1e-6]) -> boolean */
static int l_plate_overlap(lua_State *L) {
  gr_plate *p = *check_plate(L);
  int i = part_index(L, p, 2), j = part_index(L, p, 3);
  double tol = luaL_optnumber(L, 4, 1e-6);
  luaL_argcheck(L, tol >= 0, 4, "tolerance must be >= 0 mm");
  lua_pushboolean(L, gr_plate_overlap(p, i, j, tol));
  return 1;
}

/* plate:map(i, {l1, l2, ...}): the part's laser k (1-based) becomes laser lk */
static int l_plate_map(lua_State *L) {
  gr_plate *p = *check_plate(L);
  int i = part_index(L, p, 2);
  luaL_checktype(L, 3, LUA_TTABLE);
  int n = (int)luaL_len(L, 3);
  luaL_argcheck(L, n >= 1 && n <= GR_CLI_MAXSTYLES / 3, 3, "a list of 1-based laser numbers expected");
  int *map = lua_newuserdatauv(L, (size_t)n * sizeof *map, 0);
  for (int k = 0; k < n; k++) {
    lua_geti(L, 3, k + 1);
    int ok;
    lua_Integer v = lua_tointegerx(L, -1, &ok);
    if (!ok) return luaL_argerror(L, 3, "laser numbers (integers) expected");
    map[k] = (int)v - 1;
    lua_pop(L, 1);
  }
  gr_err e;
  gr_err_clear(&e);
  if (gr_plate_map_lasers(p, i, map, n, &e)) return gr_lua_error(L, &e);
  return 0;
}

/* plate:write(out, {layer=mm, format="ascii"|"binary"|"binary-long", units=0.001, lasers=1, keep=g})
 * -> {layers=, lo={x,y,z}, hi={x,y,z}, blocks=, length=, form=}, kept layer or nil */
static int l_plate_write(lua_State *L) {
  gr_plate *p = *check_plate(L);
  const char *out = luaL_checkstring(L, 2);
  luaL_checktype(L, 3, LUA_TTABLE);
  static const char *const formats[] = {"ascii", "binary", "binary-long", NULL};
  lua_getfield(L, 3, "format");
  int f = luaL_checkoption(L, -1, "ascii", formats);
  lua_pop(L, 1);
  gr_plate_opts o = {.layer_mm = gr_opt_number(L, 3, "layer", 0), .binary = f > 0, .short_form = f == 1,
                     .units = gr_opt_number(L, 3, "units", 0.001), .nlasers = gr_opt_integer(L, 3, "lasers", 1),
                     .keep = gr_opt_integer(L, 3, "keep", 0)};
  const char *dest = gr_lua_stage(L, out);
  gr_plate_info in;
  gr_err e;
  gr_err_clear(&e);
  if (gr_plate_write(p, dest, &o, &in, &e)) return gr_lua_error(L, &e);
  lua_createtable(L, 0, 6);
  gr_lua_setint(L, "layers", in.layers);
  gr_lua_setint(L, "blocks", in.blocks);
  gr_lua_setnum(L, "length", in.length);
  lua_pushstring(L, in.form);
  lua_setfield(L, -2, "form");
  if (in.rounded_points || in.rounded_vectors) {
    lua_createtable(L, 0, 2);
    gr_lua_setint(L, "points", in.rounded_points);
    gr_lua_setint(L, "vectors", in.rounded_vectors);
    lua_setfield(L, -2, "rounded_out");
  }
  for (int b = 0; b < 2; b++) {
    const double *v = b ? in.hi : in.lo;
    lua_createtable(L, 3, 0);
    for (int d = 0; d < 3; d++) {
      lua_pushnumber(L, v[d]);
      lua_rawseti(L, -2, d + 1);
    }
    lua_setfield(L, -2, b ? "hi" : "lo");
  }
  if (in.kept) gr_push_layer(L, in.kept);
  else lua_pushnil(L);
  return 2;
}

/* polygon {{x, y}, ...} at idx as x, y pairs (userdata on the stack keeps them) */
static double *poly_arg(lua_State *L, int idx, size_t *n) {
  luaL_checktype(L, idx, LUA_TTABLE);
  *n = (size_t)luaL_len(L, idx);
  double *xy = lua_newuserdatauv(L, (*n ? *n : 1) * 2 * sizeof *xy, 0);
  for (size_t k = 0; k < *n; k++) {
    lua_geti(L, idx, (lua_Integer)k + 1);
    for (int d = 0; d < 2; d++) {
      int ok = lua_type(L, -1) == LUA_TTABLE;
      if (ok) {
        lua_geti(L, -1, d + 1);
        xy[2 * k + d] = lua_tonumberx(L, -1, &ok);
        lua_pop(L, 1);
      }
      if (!ok || !isfinite(xy[2 * k + d])) luaL_argerror(L, idx, "a polygon {{x, y}, ...} of finite numbers expected");
    }
    lua_pop(L, 1);
  }
  return xy;
}

/* gradus.cli.overlap(a, b [, tol=1e-6]) -> boolean: convex polygons overlapping by more than tol mm */
static int l_overlap(lua_State *L) {
  size_t na, nb;
  double tol = luaL_optnumber(L, 3, 1e-6);
  luaL_argcheck(L, tol >= 0, 3, "tolerance must be >= 0 mm");
  const double *a = poly_arg(L, 1, &na), *b = poly_arg(L, 2, &nb);
  lua_pushboolean(L, gr_plate_poly_overlap(a, na, b, nb, tol));
  return 1;
}

static const luaL_Reg plate_methods[] = {{"add", l_plate_add},     {"part", l_plate_part},
                                         {"hull", l_plate_hull},   {"overlap", l_plate_overlap},
                                         {"map", l_plate_map},     {"write", l_plate_write},
                                         {NULL, NULL}};

static void plate_type(lua_State *L) {
  luaL_newmetatable(L, PLATE_MT);
  luaL_newlib(L, plate_methods);
  lua_setfield(L, -2, "__index");
  lua_pushcfunction(L, l_plate_gc);
  lua_setfield(L, -2, "__gc");
  lua_pushcfunction(L, l_plate_gc);
  lua_setfield(L, -2, "__close");
  lua_pop(L, 1);
}

int gr_open_clicat(lua_State *L) {
  lua_getfield(L, -1, "cli");
  lua_pushcfunction(L, l_cat);
  lua_setfield(L, -2, "cat");
  lua_pushcfunction(L, l_plate_new);
  lua_setfield(L, -2, "plate");
  lua_pushcfunction(L, l_overlap);
  lua_setfield(L, -2, "overlap");
  lua_pop(L, 1);
  plate_type(L);
  return 0;
}
