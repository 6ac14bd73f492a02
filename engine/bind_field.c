/* bind_field.c: Lua binding of the field primitive: the gradus.field table
 * (constructors) and the methods of field userdata. Every argument that
 * stands for a field goes through gr_to_field, so numbers, expression strings
 * and Lua functions are accepted wherever a field is. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "bind.h"
#include "domain.h"

#define GRID_MT "gradus.field.grid" /* temporary owner of a sampled grid */

/* ---- Lua-function fields ---- */
typedef struct lua_cb {
  lua_State *main; /* the state's main thread (never stale, unlike a coroutine) */
  int ref;         /* registry reference to the function */
} lua_cb;

/* Call the function once per point on the main thread, in protected mode;
 * a Lua error becomes a gr_err naming the point. */
static int lua_cb_eval(void *ud, size_t n, const double *x, const double *y,
                       const double *z, double *out, gr_err *e) {
  lua_cb *cb = ud;
  lua_State *M = cb->main;
  if (!lua_checkstack(M, 5))
    return gr_fail(e, GR_EMEM, "Lua field function: stack overflow");
  for (size_t i = 0; i < n; i++) {
    lua_rawgeti(M, LUA_REGISTRYINDEX, cb->ref);
    lua_pushnumber(M, x[i]);
    lua_pushnumber(M, y[i]);
    lua_pushnumber(M, z[i]);
    if (lua_pcall(M, 3, 1, 0) != LUA_OK) {
      const char *msg = lua_tostring(M, -1);
      gr_fail(e, GR_EARG, "Lua field function failed at x=%.6g, y=%.6g, z=%.6g: %s", x[i], y[i],
              z[i], msg ? msg : "(error object is not a string)");
      lua_pop(M, 1);
      return GR_EARG;
    }
    int ok;
    out[i] = lua_tonumberx(M, -1, &ok);
    if (!ok) {
      gr_fail(e, GR_EARG, "Lua field function returned %s at x=%.6g, y=%.6g, z=%.6g, expected a number",
              luaL_typename(M, -1), x[i], y[i], z[i]);
      lua_pop(M, 1);
      return GR_EARG;
    }
    lua_pop(M, 1);
  }
  return GR_OK;
}

static void lua_cb_free(void *ud) {
  lua_cb *cb = ud;
  luaL_unref(cb->main, LUA_REGISTRYINDEX, cb->ref);
  free(cb);
}

/* Field from the Lua function at idx (not thread-safe; gradient by central
 * differences). */
static gr_field *field_from_function(lua_State *L, int idx) {
  lua_cb *cb = malloc(sizeof *cb);
  if (!cb) luaL_error(L, "out of memory");
  lua_rawgeti(L, LUA_REGISTRYINDEX, LUA_RIDX_MAINTHREAD);
  cb->main = lua_tothread(L, -1);
  lua_pop(L, 1);
  lua_pushvalue(L, idx);
  cb->ref = luaL_ref(L, LUA_REGISTRYINDEX);
  gr_field *f = gr_field_callback(lua_cb_eval, NULL, cb, lua_cb_free, 0, "lua function");
  if (!f) {
    lua_cb_free(cb);
    luaL_error(L, "out of memory");
  }
  return f;
}

gr_field *gr_to_field(lua_State *L, int idx) {
  idx = lua_absindex(L, idx);
  switch (lua_type(L, idx)) {
  case LUA_TUSERDATA:
    return gr_field_ref(gr_check_field(L, idx));
  case LUA_TNUMBER: {
    gr_field *f = gr_field_constant(lua_tonumber(L, idx));
    if (!f) luaL_error(L, "out of memory");
    return f;
  }
  case LUA_TSTRING: {
    gr_err e = {0};
    gr_field *f = gr_field_expr(lua_tostring(L, idx), &e);
    if (!f) gr_lua_error(L, &e);
    return f;
  }
  case LUA_TFUNCTION:
    return field_from_function(L, idx);
  }
  luaL_typeerror(L, idx, "field, number, expression string or function");
  return NULL;
}

/* Convert argument idx to a field userdata in place (the stack then owns
 * the reference, so a later error cannot leak it) and return the field. */
static gr_field *arg_field(lua_State *L, int idx) {
  if (lua_type(L, idx) == LUA_TUSERDATA) return gr_check_field(L, idx);
  gr_field *f = gr_to_field(L, idx);
  gr_push_field(L, f);
  lua_replace(L, idx);
  return f;
}

static int push_new(lua_State *L, gr_field *f) {
  if (!f) return luaL_error(L, "out of memory creating a field");
  gr_push_field(L, f);
  return 1;
}

/* ---- gradus.field.* ---- */

/* tpms(name, {cell=2 (or {Lx,Ly,Lz}: stretched), origin={x,y,z}, level=0}) */
static int l_tpms(lua_State *L) {
  const char *name = luaL_checkstring(L, 1);
  double cell[3] = {2, 2, 2};
  gr_opt_vec(L, 2, "cell", 3, cell);
  double origin[3] = {0, 0, 0}, level = gr_opt_number(L, 2, "level", 0.0);
  gr_opt_vec(L, 2, "origin", 3, origin);
  gr_err e = {0};
  gr_field *f = gr_field_tpms3(name, cell, origin, level, &e);
  if (!f) {
    if (gr_tpms_lookup(name) < 0) return luaL_argerror(L, 1, e.msg);
    return luaL_argerror(L, 2, e.msg);
  }
  return push_new(L, f);
}

static int l_surfaces(lua_State *L) {
  lua_createtable(L, gr_tpms_count(), 0);
  for (int i = 0; i < gr_tpms_count(); i++) {
    lua_pushstring(L, gr_tpms_name(i));
    lua_rawseti(L, -2, i + 1);
  }
  return 1;
}

static int l_expr(lua_State *L) {
  luaL_checktype(L, 1, LUA_TSTRING);
  return push_new(L, gr_to_field(L, 1));
}

static int l_lua(lua_State *L) {
  luaL_checktype(L, 1, LUA_TFUNCTION);
  return push_new(L, gr_to_field(L, 1));
}

static int l_constant(lua_State *L) {
  double c = luaL_checknumber(L, 1);
  luaL_argcheck(L, isfinite(c), 1, "constant must be finite");
  return push_new(L, gr_field_constant(c));
}

static gr_field *expr_or_raise(lua_State *L, const char *src) {
  gr_err e = {0};
  gr_field *f = gr_field_expr(src, &e);
  if (!f) gr_lua_error(L, &e);
  return f;
}

/* Shortest text that reads back as v exactly. */
static void fmt_num(char *buf, size_t n, double v) {
  for (int prec = 15; prec <= 17; prec++) {
    snprintf(buf, n, "%.*g", prec, v);
    if (strtod(buf, NULL) == v) return;
  }
}

/* "(x-c)" or "x" when c is 0, appended to src. */
static void add_axis(char *src, size_t n, char axis, double c) {
  char num[40], term[64];
  fmt_num(num, sizeof num, c);
  if (c == 0) snprintf(term, sizeof term, "%c^2", axis);
  else snprintf(term, sizeof term, "(%c-(%s))^2", axis, num);
  size_t k = strlen(src);
  snprintf(src + k, n - k, "%s%s", k > 5 ? "+" : "", term);
}

/* sphere(r, {center={x,y,z}}): signed distance |p - c| - r. */
static int l_sphere(lua_State *L) {
  double r = luaL_checknumber(L, 1), c[3] = {0, 0, 0};
  if (!(r > 0) || !isfinite(r))
    return luaL_argerror(L, 1, lua_pushfstring(L, "radius must be > 0, got %f", r));
  gr_opt_vec(L, 2, "center", 3, c);
  char src[256] = "sqrt(", num[40];
  for (int i = 0; i < 3; i++) add_axis(src, sizeof src, "xyz"[i], c[i]);
  fmt_num(num, sizeof num, r);
  size_t k = strlen(src);
  snprintf(src + k, sizeof src - k, ")-%s", num);
  return push_new(L, expr_or_raise(L, src));
}

/* distance(f, {band=mm, cell=mm, box={x0,y0,z0,x1,y1,z1}}): f (negative
 * inside, any scale) as a signed distance to its zero set, exact within band;
 * f itself where it is a distance already (over box, if given; domain.h). */
static int l_distance(lua_State *L) {
  double box[6];
  int has_box = gr_opt_vec(L, 2, "box", 6, box);
  gr_field *f = gr_to_field(L, 1);
  gr_err e;
  gr_err_clear(&e);
  gr_field *d = gr_domain_distance(f, gr_opt_number(L, 2, "band", 1), gr_opt_number(L, 2, "cell", 1),
                                   has_box ? box : NULL, &e);
  gr_field_free(f);
  if (!d) return gr_lua_error(L, &e);
  gr_push_field(L, d);
  return 1;
}

/* cylinder(r, {center={x,y}}): distance to a z-parallel cylinder. */
static int l_cylinder(lua_State *L) {
  double r = luaL_checknumber(L, 1), c[2] = {0, 0};
  if (!(r > 0) || !isfinite(r))
    return luaL_argerror(L, 1, lua_pushfstring(L, "radius must be > 0, got %f", r));
  gr_opt_vec(L, 2, "center", 2, c);
  char src[256] = "sqrt(", num[40];
  for (int i = 0; i < 2; i++) add_axis(src, sizeof src, "xy"[i], c[i]);
  fmt_num(num, sizeof num, r);
  size_t k = strlen(src);
  snprintf(src + k, sizeof src - k, ")-%s", num);
  return push_new(L, expr_or_raise(L, src));
}

static int l_min(lua_State *L) {
  gr_field *a = arg_field(L, 1), *b = arg_field(L, 2);
  return push_new(L, gr_field_min(a, b));
}

static int l_max(lua_State *L) {
  gr_field *a = arg_field(L, 1), *b = arg_field(L, 2);
  return push_new(L, gr_field_max(a, b));
}

static int l_blend(lua_State *L) {
  gr_field *a = arg_field(L, 1), *b = arg_field(L, 2), *w = arg_field(L, 3);
  return push_new(L, gr_field_blend(a, b, w));
}

/* ---- methods ---- */
static double check_finite(lua_State *L, int idx, const char *what) {
  double v = luaL_checknumber(L, idx);
  if (!isfinite(v)) luaL_argerror(L, idx, lua_pushfstring(L, "%s must be finite", what));
  return v;
}

static int m_eval(lua_State *L) {
  gr_field *f = gr_check_field(L, 1);
  double x = check_finite(L, 2, "x"), y = check_finite(L, 3, "y"), z = check_finite(L, 4, "z"), v;
  gr_err e = {0};
  if (gr_field_eval(f, 1, &x, &y, &z, &v, &e)) return gr_lua_error(L, &e);
  lua_pushnumber(L, v);
  return 1;
}

static int m_grad(lua_State *L) {
  gr_field *f = gr_check_field(L, 1);
  double x = check_finite(L, 2, "x"), y = check_finite(L, 3, "y"), z = check_finite(L, 4, "z");
  double g[3];
  gr_err e = {0};
  if (gr_field_grad(f, 1, &x, &y, &z, g, g + 1, g + 2, &e)) return gr_lua_error(L, &e);
  for (int i = 0; i < 3; i++) lua_pushnumber(L, g[i]);
  return 3;
}

/* eval_many(xs, ys, zs) -> {v1, v2, ...}; buffers are userdata, so an error
 * part way leaks nothing. */
static int m_eval_many(lua_State *L) {
  gr_field *f = gr_check_field(L, 1);
  for (int a = 2; a <= 4; a++) luaL_checktype(L, a, LUA_TTABLE);
  lua_Integer n = luaL_len(L, 2);
  for (int a = 3; a <= 4; a++)
    if (luaL_len(L, a) != n)
      return luaL_argerror(L, a, lua_pushfstring(L, "length %d differs from xs length %d",
                                                 (int)luaL_len(L, a), (int)n));
  size_t cnt = (size_t)n;
  double *buf = lua_newuserdatauv(L, (cnt ? cnt : 1) * 4 * sizeof *buf, 0);
  double *c[3] = {buf, buf + cnt, buf + 2 * cnt}, *out = buf + 3 * cnt;
  for (int a = 0; a < 3; a++)
    for (size_t i = 0; i < cnt; i++) {
      lua_geti(L, 2 + a, (lua_Integer)i + 1);
      int ok;
      c[a][i] = lua_tonumberx(L, -1, &ok);
      if (!ok)
        return luaL_argerror(L, 2 + a, lua_pushfstring(L, "item %d is not a number", (int)i + 1));
      lua_pop(L, 1);
    }
  gr_err e = {0};
  if (gr_field_eval(f, cnt, c[0], c[1], c[2], out, &e)) return gr_lua_error(L, &e);
  lua_createtable(L, (int)cnt, 0);
  for (size_t i = 0; i < cnt; i++) {
    lua_pushnumber(L, out[i]);
    lua_rawseti(L, -2, (lua_Integer)i + 1);
  }
  return 1;
}

/* translate(dx, dy, dz) or translate({dx, dy, dz}) */
static int m_translate(lua_State *L) {
  gr_field *f = gr_check_field(L, 1);
  double d[3];
  if (lua_type(L, 2) == LUA_TTABLE) {
    for (int i = 0; i < 3; i++) {
      lua_geti(L, 2, i + 1);
      int ok;
      d[i] = lua_tonumberx(L, -1, &ok);
      if (!ok || !isfinite(d[i])) return luaL_argerror(L, 2, "{dx, dy, dz} of finite numbers expected");
      lua_pop(L, 1);
    }
  } else {
    d[0] = check_finite(L, 2, "dx");
    d[1] = luaL_optnumber(L, 3, 0);
    d[2] = luaL_optnumber(L, 4, 0);
    if (!isfinite(d[1]) || !isfinite(d[2])) return luaL_error(L, "translation must be finite");
  }
  return push_new(L, gr_field_translate(f, d));
}

static int m_scale(lua_State *L) {
  gr_field *f = gr_check_field(L, 1);
  double s = luaL_checknumber(L, 2);
  if (!(s > 0) || !isfinite(s))
    return luaL_argerror(L, 2, lua_pushfstring(L, "scale must be > 0, got %f", s));
  return push_new(L, gr_field_scale(f, s));
}

static int m_negate(lua_State *L) { return push_new(L, gr_field_negate(gr_check_field(L, 1))); }

static int m_union(lua_State *L) {
  gr_field *a = gr_check_field(L, 1), *b = arg_field(L, 2);
  return push_new(L, gr_field_min(a, b));
}

static int m_intersect(lua_State *L) {
  gr_field *a = gr_check_field(L, 1), *b = arg_field(L, 2);
  return push_new(L, gr_field_max(a, b));
}

static int m_describe(lua_State *L) {
  lua_pushstring(L, gr_field_describe(gr_check_field(L, 1)));
  return 1;
}

static int m_lipschitz(lua_State *L) {
  lua_pushnumber(L, gr_field_lipschitz(gr_check_field(L, 1)));
  return 1;
}

static int m_tostring(lua_State *L) {
  gr_field *f = gr_check_field(L, 1);
  lua_pushfstring(L, "field %s", gr_field_describe(f));
  return 1;
}

typedef struct grid_box { gr_grid3 *g3; gr_grid2 *g2; } grid_box;

static int grid_gc(lua_State *L) {
  grid_box *b = luaL_checkudata(L, 1, GRID_MT);
  gr_grid3_free(b->g3);
  gr_grid2_free(b->g2);
  b->g3 = NULL;
  b->g2 = NULL;
  return 0;
}

static void read_ints(lua_State *L, int idx, const char *key, int n, int *out) {
  double v[3];
  if (!gr_opt_vec(L, idx, key, n, v))
    luaL_error(L, "bad option '%s' (missing; %d numbers expected)", key, n);
  for (int i = 0; i < n; i++) {
    if (v[i] != floor(v[i]) || v[i] < -1e9 || v[i] > 1e9)
      luaL_error(L, "bad option '%s' (item %d must be an integer, got %f)", key, i + 1, v[i]);
    out[i] = (int)v[i];
  }
}

static void read_vec(lua_State *L, int idx, const char *key, int n, double *out) {
  if (!gr_opt_vec(L, idx, key, n, out))
    luaL_error(L, "bad option '%s' (missing; %d numbers expected)", key, n);
}

/* Flat values table t[1 + i + nx*(j + ny*k)] plus the grid's geometry. */
static void push_values(lua_State *L, const double *v, size_t cnt) {
  lua_createtable(L, (int)cnt, 9);
  for (size_t i = 0; i < cnt; i++) {
    lua_pushnumber(L, v[i]);
    lua_rawseti(L, -2, (lua_Integer)i + 1);
  }
}

/* sample{lo={x,y,z}, hi={x,y,z}, n={nx,ny,nz}} */
static int m_sample(lua_State *L) {
  gr_field *f = gr_check_field(L, 1);
  luaL_checktype(L, 2, LUA_TTABLE);
  double lo[3], hi[3];
  int n[3];
  read_vec(L, 2, "lo", 3, lo);
  read_vec(L, 2, "hi", 3, hi);
  read_ints(L, 2, "n", 3, n);
  grid_box *b = lua_newuserdatauv(L, sizeof *b, 0);
  b->g3 = NULL;
  b->g2 = NULL;
  luaL_setmetatable(L, GRID_MT);
  gr_err e = {0};
  b->g3 = gr_grid3_sample(f, lo, hi, n, &e);
  if (!b->g3) return gr_lua_error(L, &e);
  gr_grid3 *g = b->g3;
  push_values(L, g->v, (size_t)g->nx * g->ny * g->nz);
  lua_pushinteger(L, g->nx); lua_setfield(L, -2, "nx");
  lua_pushinteger(L, g->ny); lua_setfield(L, -2, "ny");
  lua_pushinteger(L, g->nz); lua_setfield(L, -2, "nz");
  gr_lua_setnum(L, "x0", g->x0); gr_lua_setnum(L, "y0", g->y0); gr_lua_setnum(L, "z0", g->z0);
  gr_lua_setnum(L, "hx", g->hx); gr_lua_setnum(L, "hy", g->hy); gr_lua_setnum(L, "hz", g->hz);
  gr_grid3_free(b->g3);
  b->g3 = NULL;
  return 1;
}

/* sample2{z=, lo={x,y}, hi={x,y}, n={nx,ny}} */
static int m_sample2(lua_State *L) {
  gr_field *f = gr_check_field(L, 1);
  luaL_checktype(L, 2, LUA_TTABLE);
  double lo[2], hi[2], z = gr_opt_number(L, 2, "z", 0.0);
  int n[2];
  read_vec(L, 2, "lo", 2, lo);
  read_vec(L, 2, "hi", 2, hi);
  read_ints(L, 2, "n", 2, n);
  grid_box *b = lua_newuserdatauv(L, sizeof *b, 0);
  b->g3 = NULL;
  b->g2 = NULL;
  luaL_setmetatable(L, GRID_MT);
  gr_err e = {0};
  b->g2 = gr_grid2_sample(f, z, lo, hi, n, &e);
  if (!b->g2) return gr_lua_error(L, &e);
  gr_grid2 *g = b->g2;
  push_values(L, g->v, (size_t)g->nx * g->ny);
  lua_pushinteger(L, g->nx); lua_setfield(L, -2, "nx");
  lua_pushinteger(L, g->ny); lua_setfield(L, -2, "ny");
  gr_lua_setnum(L, "x0", g->x0); gr_lua_setnum(L, "y0", g->y0); gr_lua_setnum(L, "z", g->z);
  gr_lua_setnum(L, "hx", g->hx); gr_lua_setnum(L, "hy", g->hy);
  gr_grid2_free(b->g2);
  b->g2 = NULL;
  return 1;
}

static const luaL_Reg field_fns[] = {
  {"tpms", l_tpms},     {"surfaces", l_surfaces}, {"expr", l_expr},
  {"lua", l_lua},       {"constant", l_constant}, {"sphere", l_sphere},
  {"cylinder", l_cylinder}, {"min", l_min},       {"max", l_max},
  {"blend", l_blend},   {"distance", l_distance}, {NULL, NULL}};

static const luaL_Reg field_methods[] = {
  {"eval", m_eval},           {"eval_many", m_eval_many}, {"grad", m_grad},
  {"translate", m_translate}, {"scale", m_scale},         {"negate", m_negate},
  {"union", m_union},         {"intersect", m_intersect}, {"sample", m_sample},
  {"sample2", m_sample2},     {"describe", m_describe},   {"lipschitz", m_lipschitz},
  {"__tostring", m_tostring}, {NULL, NULL}};

int gr_open_field(lua_State *L) {
  luaL_newmetatable(L, GRID_MT);
  lua_pushcfunction(L, grid_gc);
  lua_setfield(L, -2, "__gc");
  lua_pop(L, 1);
  gr_add_methods(L, GR_MT_FIELD, field_methods);
  luaL_newlib(L, field_fns);
  lua_setfield(L, -2, "field");
  return 0;
}
