/* bind_distance.c: Lua binding of the distance primitive.
 *   gradus.distance.offset{surface=field, cell=2 (or {Lx,Ly,Lz}), origin={x,y,z}, lo={..}, hi={..},
 *       margin=0, res=40, thickness=expr|number, inside=expr, kind="sheet"|"network",
 *       side=-1, mode="exact"|"mesh", mesh=mesh} -> field
 * The field is g = d - T(q) (sheet) or sd - T(q) (network): negative inside the
 * solid; its zero set is the graded offset surface. */
#include <math.h>
#include <string.h>
#include "bind.h"
#include "distance.h"

static int l_offset(lua_State *L) {
  luaL_checktype(L, 1, LUA_TTABLE);
  gr_offset_opts o = gr_offset_defaults();
  lua_getfield(L, 1, "surface");
  if (lua_isnil(L, -1)) return luaL_error(L, "bad option 'surface' (a field or a TPMS name is needed)");
  gr_field *phi;
  double cell[3] = {2, 2, 2}; /* a number (a cube) or {Lx, Ly, Lz} */
  gr_opt_vec(L, 1, "cell", 3, cell);
  double origin[3] = {0, 0, 0};
  gr_opt_vec(L, 1, "origin", 3, origin);
  if (lua_type(L, -1) == LUA_TSTRING && gr_tpms_lookup(lua_tostring(L, -1)) >= 0) {
    gr_err e;
    gr_err_clear(&e);
    phi = gr_field_tpms3(lua_tostring(L, -1), cell, origin, gr_opt_number(L, 1, "level", 0), &e);
    if (!phi) return gr_lua_error(L, &e);
  } else {
    phi = gr_to_field(L, -1);
  }
  lua_pop(L, 1);
  o.surface = phi;
  memcpy(o.cell, cell, sizeof cell);
  memcpy(o.origin, origin, sizeof origin);
  double lo[3] = {origin[0], origin[1], origin[2]}, hi[3] = {origin[0] + cell[0], origin[1] + cell[1], origin[2] + cell[2]};
  gr_opt_vec(L, 1, "lo", 3, lo);
  gr_opt_vec(L, 1, "hi", 3, hi);
  memcpy(o.box_lo, lo, sizeof lo);
  memcpy(o.box_hi, hi, sizeof hi);
  o.margin = gr_opt_number(L, 1, "margin", 0.2);
  o.voxel = gr_opt_boolean(L, 1, "voxel", 0); /* u, v, w relative to the voxel [lo, lo + cell] */
  o.res = gr_opt_integer(L, 1, "res", 40);
  lua_getfield(L, 1, "thickness");
  if (lua_type(L, -1) == LUA_TNUMBER) {
    o.thickness = lua_tonumber(L, -1);
  } else if (lua_type(L, -1) == LUA_TSTRING) {
    o.thickness_expr = lua_tostring(L, -1);
  } else if (lua_isfunction(L, -1) || luaL_testudata(L, -1, GR_MT_FIELD)) {
    o.thickness_field = gr_to_field(L, -1); /* T(x, y, z) of q's global coordinates */
  } else if (!lua_isnil(L, -1)) {
    gr_field_free(phi);
    return luaL_error(L, "bad option 'thickness' (number, expression in x,y,z,u,v,w,L, or function of x,y,z expected, got %s)", luaL_typename(L, -1));
  }
  lua_pop(L, 1);
  lua_getfield(L, 1, "density_table"); /* thickness values are densities (gradus.density) */
  o.density = gr_test_dtable(L, -1);
  lua_pop(L, 1);
  o.inside_expr = gr_opt_string(L, 1, "inside", NULL);
  const char *kind = gr_opt_string(L, 1, "kind", "sheet");
  if (strcmp(kind, "sheet") && strcmp(kind, "network")) {
    gr_field_free(phi);
    return luaL_error(L, "bad option 'kind' (sheet or network, got '%s')", kind);
  }
  o.kind = strcmp(kind, "sheet") ? GR_OFFSET_NETWORK : GR_OFFSET_SHEET;
  o.side = gr_opt_integer(L, 1, "side", -1);
  const char *mode = gr_opt_string(L, 1, "mode", "exact");
  if (strcmp(mode, "exact") && strcmp(mode, "mesh")) {
    gr_field_free(phi);
    return luaL_error(L, "bad option 'mode' (exact or mesh, got '%s')", mode);
  }
  o.mode = strcmp(mode, "exact") ? GR_DIST_MESH : GR_DIST_EXACT;
  lua_getfield(L, 1, "mesh");
  if (!lua_isnil(L, -1)) {
    o.mesh = gr_check_mesh(L, -1);
    lua_pushvalue(L, -1); /* keep alive in the field's user value, below */
  }
  gr_err e;
  gr_err_clear(&e);
  gr_field *g = gr_offset_field_new(&o, &e);
  gr_field_free(phi);
  gr_field_free(o.thickness_field);
  if (!g) return gr_lua_error(L, &e);
  gr_push_field(L, g);
  if (o.mesh) {
    lua_pushvalue(L, -2);
    lua_setiuservalue(L, -2, 1);
  }
  const char *w = gr_offset_warning(g);
  if (w[0]) {
    lua_pushstring(L, w);
    return 2;
  }
  return 1;
}

/* gradus.distance.closest(mesh, x, y, z) -> qx, qy, qz, distance, triangle (1-based) */
static int l_closest(lua_State *L) {
  gr_mesh *m = gr_check_mesh(L, 1);
  double p[3] = {luaL_checknumber(L, 2), luaL_checknumber(L, 3), luaL_checknumber(L, 4)};
  gr_err e;
  gr_err_clear(&e);
  gr_bvh *b = gr_bvh_new(m, &e);
  if (!b) return gr_lua_error(L, &e);
  gr_hit h;
  gr_bvh_closest(b, p, INFINITY, &h);
  gr_bvh_free(b);
  for (int a = 0; a < 3; a++) lua_pushnumber(L, h.q[a]);
  lua_pushnumber(L, h.dist);
  lua_pushinteger(L, h.tri + 1);
  return 5;
}

static const luaL_Reg fns[] = {{"offset", l_offset}, {"closest", l_closest}, {NULL, NULL}};

int gr_open_distance(lua_State *L) {
  luaL_newlib(L, fns);
  lua_setfield(L, -2, "distance");
  return 0;
}
