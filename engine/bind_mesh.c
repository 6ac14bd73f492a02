/* bind_mesh.c: Lua binding of meshes and marching cubes: gradus.mc,
 * gradus.mesh.read/new/solid and the mesh methods. */
#include <math.h>
#include "bind.h"
#include "mc.h"
#include "solid.h"

/* gradus.mc(field, {lo=, hi=, res=N | n={nx,ny,nz}, refine=false}) */
static int l_mc(lua_State *L) {
  luaL_checktype(L, 2, LUA_TTABLE);
  double lo[3], hi[3];
  if (!gr_opt_vec(L, 2, "lo", 3, lo)) return luaL_argerror(L, 2, "option 'lo' is required");
  if (!gr_opt_vec(L, 2, "hi", 3, hi)) return luaL_argerror(L, 2, "option 'hi' is required");
  double nd[3];
  int n[3];
  if (!gr_opt_vec(L, 2, "n", 3, nd)) {
    double r = gr_opt_number(L, 2, "res", 40);
    nd[0] = nd[1] = nd[2] = r;
  }
  for (int i = 0; i < 3; i++) {
    if (!(nd[i] >= 2) || nd[i] > 1e6)
      return luaL_error(L, "bad option 'res' (samples per axis must be >= 2, got %f)", nd[i]);
    n[i] = (int)nd[i];
  }
  double mem = (double)n[0] * n[1] * 88.0;
  if (mem > 4e9)
    return luaL_error(L, "bad option 'res' (a %d x %d slab needs about %.1f GB)", n[0], n[1], mem / 1e9);
  int refine = gr_opt_boolean(L, 2, "refine", 0);
  double iso = gr_opt_number(L, 2, "iso", 0);
  gr_field *f = gr_to_field(L, 1);
  gr_err e;
  gr_mesh *m;
  if (iso != 0) {
    gr_grid3 *g = gr_grid3_sample(f, lo, hi, n, &e);
    m = g ? gr_mc(g, iso, &e) : NULL;
    gr_grid3_free(g);
  } else {
    m = gr_mc_field(f, lo, hi, n, refine, &e);
  }
  gr_field_free(f);
  if (!m) return gr_lua_error(L, &e);
  gr_push_mesh(L, m);
  return 1;
}

static int l_read(lua_State *L) {
  const char *path = luaL_checkstring(L, 1);
  gr_lua_guard(L, path, "r");
  gr_err e;
  gr_mesh *m = gr_mesh_read(path, &e);
  if (!m) return gr_lua_error(L, &e);
  gr_push_mesh(L, m);
  return 1;
}

static int l_new(lua_State *L) {
  gr_mesh *m = gr_mesh_new();
  if (!m) return luaL_error(L, "out of memory");
  gr_push_mesh(L, m);
  return 1;
}

/* gradus.mesh.box({x0, y0, z0}, {x1, y1, z1}) -> the box as 12 outward triangles */
static double box_coord(lua_State *L, int arg, int k) {
  luaL_checktype(L, arg, LUA_TTABLE);
  lua_geti(L, arg, k);
  int ok;
  double v = lua_tonumberx(L, -1, &ok);
  lua_pop(L, 1);
  if (!ok || !isfinite(v)) luaL_argerror(L, arg, "expected a table of 3 finite numbers (mm)");
  return v;
}
static int l_box(lua_State *L) {
  double lo[3], hi[3];
  for (int k = 0; k < 3; k++) lo[k] = box_coord(L, 1, k + 1), hi[k] = box_coord(L, 2, k + 1);
  for (int k = 0; k < 3; k++)
    if (!(hi[k] > lo[k])) return luaL_error(L, "gradus.mesh.box: the box is empty along %c (%f >= %f mm)", "xyz"[k], lo[k], hi[k]);
  static const int F[12][3] = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
                               {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};
  gr_mesh *m = gr_mesh_new();
  int bad = !m;
  for (int v = 0; v < 8 && !bad; v++)
    bad = gr_mesh_add_vertex(m, v & 1 ? hi[0] : lo[0], v & 2 ? hi[1] : lo[1], v & 4 ? hi[2] : lo[2]) < 0;
  for (int f = 0; f < 12 && !bad; f++) bad = gr_mesh_add_face(m, F[f][0], F[f][1], F[f][2]) != 0;
  if (bad) { gr_mesh_free(m); return luaL_error(L, "out of memory"); }
  gr_push_mesh(L, m);
  return 1;
}

/* gradus.mesh.solid(mesh) or mesh:solid() -> the part's signed distance field */
static int l_solid(lua_State *L) {
  gr_mesh *m = gr_check_mesh(L, 1);
  gr_err e;
  gr_field *f = gr_solid_field(m, &e);
  if (!f) return gr_lua_error(L, &e);
  gr_push_field(L, f);
  return 1;
}

static int m_write(lua_State *L) {
  gr_mesh *m = gr_check_mesh(L, 1);
  gr_err e;
  const char *format = luaL_optstring(L, 3, NULL);
  if (gr_mesh_write(m, gr_lua_stage(L, luaL_checkstring(L, 2)), format, &e))
    return gr_lua_error(L, &e);
  lua_settop(L, 1);
  return 1;
}

static int m_counts(lua_State *L) {
  gr_mesh *m = gr_check_mesh(L, 1);
  lua_pushinteger(L, (lua_Integer)m->nv);
  lua_pushinteger(L, (lua_Integer)m->nf);
  return 2;
}

static int m_area(lua_State *L) { lua_pushnumber(L, gr_mesh_area(gr_check_mesh(L, 1))); return 1; }
static int m_volume(lua_State *L) { lua_pushnumber(L, gr_mesh_volume(gr_check_mesh(L, 1))); return 1; }

static void push_vec(lua_State *L, const double *p) {
  lua_createtable(L, 3, 0);
  for (int i = 0; i < 3; i++) { lua_pushnumber(L, p[i]); lua_rawseti(L, -2, i + 1); }
}

static int m_bounds(lua_State *L) {
  double lo[3], hi[3];
  gr_mesh_bounds(gr_check_mesh(L, 1), lo, hi);
  push_vec(L, lo);
  push_vec(L, hi);
  return 2;
}

static int m_topology(lua_State *L) {
  gr_mesh *m = gr_check_mesh(L, 1);
  gr_mesh_topo t;
  gr_err e;
  if (gr_mesh_topology(m, &t, &e)) return gr_lua_error(L, &e);
  lua_createtable(L, 0, 6);
  lua_pushinteger(L, (lua_Integer)t.edges); lua_setfield(L, -2, "edges");
  lua_pushinteger(L, (lua_Integer)t.boundary_edges); lua_setfield(L, -2, "boundary_edges");
  lua_pushinteger(L, (lua_Integer)t.nonmanifold_edges); lua_setfield(L, -2, "nonmanifold_edges");
  lua_pushinteger(L, (lua_Integer)t.misoriented_edges); lua_setfield(L, -2, "misoriented_edges");
  lua_pushinteger(L, (lua_Integer)t.degenerate_faces); lua_setfield(L, -2, "degenerate_faces");
  lua_pushinteger(L, (lua_Integer)t.euler); lua_setfield(L, -2, "euler");
  return 1;
}

static int m_vertex(lua_State *L) {
  gr_mesh *m = gr_check_mesh(L, 1);
  lua_Integer i = luaL_checkinteger(L, 2);
  luaL_argcheck(L, i >= 1 && (size_t)i <= m->nv, 2, "vertex index out of range");
  for (int d = 0; d < 3; d++) lua_pushnumber(L, m->v[3 * (size_t)(i - 1) + d]);
  return 3;
}

static int m_face(lua_State *L) {
  gr_mesh *m = gr_check_mesh(L, 1);
  lua_Integer i = luaL_checkinteger(L, 2);
  luaL_argcheck(L, i >= 1 && (size_t)i <= m->nf, 2, "face index out of range");
  for (int d = 0; d < 3; d++) lua_pushinteger(L, (lua_Integer)m->f[3 * (size_t)(i - 1) + d] + 1);
  return 3;
}

static int m_tostring(lua_State *L) {
  gr_mesh *m = gr_check_mesh(L, 1);
  double lo[3], hi[3];
  gr_mesh_bounds(m, lo, hi);
  lua_pushfstring(L, "mesh: %I vertices, %I faces, bounds (%f, %f, %f)-(%f, %f, %f)",
                  (lua_Integer)m->nv, (lua_Integer)m->nf, lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]);
  return 1;
}

int gr_open_mesh(lua_State *L) {
  static const luaL_Reg methods[] = {
      {"write", m_write}, {"counts", m_counts}, {"area", m_area},
      {"volume", m_volume}, {"bounds", m_bounds}, {"topology", m_topology},
      {"vertex", m_vertex}, {"face", m_face}, {"solid", l_solid}, {"__tostring", m_tostring},
      {NULL, NULL}};
  gr_add_methods(L, GR_MT_MESH, methods);
  lua_pushcfunction(L, l_mc);
  lua_setfield(L, -2, "mc");
  lua_newtable(L);
  lua_pushcfunction(L, l_read);
  lua_setfield(L, -2, "read");
  lua_pushcfunction(L, l_new);
  lua_setfield(L, -2, "new");
  lua_pushcfunction(L, l_box);
  lua_setfield(L, -2, "box");
  lua_pushcfunction(L, l_solid);
  lua_setfield(L, -2, "solid");
  lua_setfield(L, -2, "mesh");
  return 0;
}
