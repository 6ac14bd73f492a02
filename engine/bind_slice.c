/* bind_slice.c: Lua binding of the slice primitive.
 *   gradus.slice.field(field, z, {lo={x,y}, hi={x,y}, cell=, hatch=, refine=true, tol=}) -> rings
 *   gradus.slice.mesh(mesh, z) -> rings, {open polylines}
 *   gradus.slice.offset(rings, b, {cell=}) -> rings
 *   gradus.slice.max_cell(hatch) -> d/2 (eq. 7)
 * rings methods: count, area, ring(i) (flat {x1,y1,...}, plus area, parent), length, contains, bounds. */
#include <math.h>
#include "bind.h"
#include "slice.h"

static int l_field(lua_State *L) {
  gr_field *f = gr_to_field(L, 1);
  double z = luaL_checknumber(L, 2);
  gr_slice_opts o = gr_slice_defaults();
  double lo[2] = {-1, -1}, hi[2] = {1, 1};
  if (!gr_opt_vec(L, 3, "lo", 2, lo) || !gr_opt_vec(L, 3, "hi", 2, hi)) {
    gr_field_free(f);
    return luaL_error(L, "bad option 'lo'/'hi' (the window {x, y} corners in mm are needed)");
  }
  o.lo[0] = lo[0]; o.lo[1] = lo[1]; o.hi[0] = hi[0]; o.hi[1] = hi[1];
  double hatch = gr_opt_number(L, 3, "hatch", 0);
  o.cell = gr_opt_number(L, 3, "cell", hatch > 0 ? hatch / 2 : (hi[0] - lo[0]) / 200);
  o.refine = gr_opt_boolean(L, 3, "refine", 1);
  o.tol = gr_opt_number(L, 3, "tol", o.tol);
  o.chord_tol = gr_opt_number(L, 3, "chord_tol", 0);
  gr_err e;
  gr_err_clear(&e);
  if (hatch > 0 && gr_slice_check_res(o.cell, hatch, &e)) { gr_field_free(f); return gr_lua_error(L, &e); }
  if (!(o.cell > 0)) { gr_field_free(f); return luaL_error(L, "bad option 'cell' (must be > 0 mm, got %f)", o.cell); }
  gr_rings *r = gr_rings_new();
  if (!r) { gr_field_free(f); return luaL_error(L, "out of memory"); }
  gr_push_rings(L, r);
  int rc = gr_slice_field(f, z, &o, r, &e);
  gr_field_free(f);
  if (rc) return gr_lua_error(L, &e);
  return 1;
}

static int l_offset(lua_State *L) {
  gr_rings *in = gr_check_rings(L, 1);
  double b = luaL_checknumber(L, 2);
  luaL_argcheck(L, b >= 0 && isfinite(b), 2, "offset must be >= 0 mm");
  double cell = gr_opt_number(L, 3, "cell", 0.0125);
  gr_rings *r = gr_rings_new();
  if (!r) return luaL_error(L, "out of memory");
  gr_push_rings(L, r);
  gr_err e;
  gr_err_clear(&e);
  if (gr_offset_rings(in, b, cell, r, &e)) return gr_lua_error(L, &e);
  return 1;
}

static int l_mesh(lua_State *L) {
  gr_mesh *m = gr_check_mesh(L, 1);
  double z = luaL_checknumber(L, 2);
  gr_rings *r = gr_rings_new();
  gr_layer *open = gr_layer_new(z);
  if (!r || !open) { gr_rings_free(r); gr_layer_free(open); return luaL_error(L, "out of memory"); }
  gr_push_rings(L, r);
  gr_push_layer(L, open);
  gr_err e;
  gr_err_clear(&e);
  if (gr_slice_mesh(m, z, r, open, &e)) return gr_lua_error(L, &e);
  return 2;
}

static int l_max_cell(lua_State *L) {
  lua_pushnumber(L, gr_slice_max_cell(luaL_checknumber(L, 1)));
  return 1;
}

static int r_count(lua_State *L) { lua_pushinteger(L, (lua_Integer)gr_check_rings(L, 1)->nrings); return 1; }
static int r_area(lua_State *L) { lua_pushnumber(L, gr_rings_area(gr_check_rings(L, 1))); return 1; }
static int r_length(lua_State *L) {
  gr_rings *r = gr_check_rings(L, 1);
  double s = 0;
  for (size_t i = 0; i < r->nrings; i++) s += gr_ring_length(r, i);
  lua_pushnumber(L, s);
  return 1;
}
static int r_contains(lua_State *L) {
  lua_pushboolean(L, gr_rings_contains(gr_check_rings(L, 1), luaL_checknumber(L, 2), luaL_checknumber(L, 3)));
  return 1;
}
static int r_ring(lua_State *L) {
  gr_rings *r = gr_check_rings(L, 1);
  lua_Integer i = luaL_checkinteger(L, 2);
  luaL_argcheck(L, i >= 1 && (size_t)i <= r->nrings, 2, "ring index out of range");
  const double *p = gr_ring_xy(r, (size_t)i - 1);
  size_t n = gr_ring_len(r, (size_t)i - 1);
  lua_createtable(L, (int)(2 * n), 2);
  for (size_t k = 0; k < 2 * n; k++) { lua_pushnumber(L, p[k]); lua_rawseti(L, -2, (lua_Integer)k + 1); }
  lua_pushnumber(L, gr_ring_area(r, (size_t)i - 1));
  lua_setfield(L, -2, "area");
  lua_pushinteger(L, r->parent ? r->parent[i - 1] + 1 : 0);
  lua_setfield(L, -2, "parent");
  return 1;
}
static int r_bounds(lua_State *L) {
  gr_rings *r = gr_check_rings(L, 1);
  double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
  for (size_t k = 0; k < r->npts; k++)
    for (int a = 0; a < 2; a++) { lo[a] = fmin(lo[a], r->xy[2 * k + a]); hi[a] = fmax(hi[a], r->xy[2 * k + a]); }
  for (int t = 0; t < 2; t++) {
    lua_createtable(L, 2, 0);
    for (int a = 0; a < 2; a++) { lua_pushnumber(L, t ? hi[a] : lo[a]); lua_rawseti(L, -2, a + 1); }
  }
  return 2;
}
static int r_tostring(lua_State *L) {
  gr_rings *r = gr_check_rings(L, 1);
  size_t outer = 0;
  for (size_t i = 0; i < r->nrings; i++) outer += gr_ring_area(r, i) > 0;
  lua_pushfstring(L, "rings: %d rings (%d outer, %d holes), area %f mm^2", (int)r->nrings, (int)outer,
                  (int)(r->nrings - outer), gr_rings_area(r));
  return 1;
}

static const luaL_Reg methods[] = {{"count", r_count},   {"area", r_area},       {"length", r_length},
                                   {"contains", r_contains}, {"ring", r_ring}, {"bounds", r_bounds},
                                   {"__tostring", r_tostring}, {NULL, NULL}};
static const luaL_Reg fns[] = {{"field", l_field}, {"offset", l_offset}, {"mesh", l_mesh}, {"max_cell", l_max_cell}, {NULL, NULL}};

int gr_open_slice(lua_State *L) {
  gr_add_methods(L, GR_MT_RINGS, methods);
  luaL_newlib(L, fns);
  lua_setfield(L, -2, "slice");
  return 0;
}
