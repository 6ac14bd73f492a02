/* bind.c: the userdata types and option readers shared by the bindings. */
#include "bind.h"
#include <string.h>

int gr_lua_error(lua_State *L, const gr_err *e) {
  return luaL_error(L, "%s", e && e->msg[0] ? e->msg : "unknown error");
}

static int opt_get(lua_State *L, int idx, const char *key) {
  if (idx == 0 || lua_isnoneornil(L, idx)) return 0;
  luaL_checktype(L, idx, LUA_TTABLE);
  lua_getfield(L, idx, key);
  if (lua_isnil(L, -1)) { lua_pop(L, 1); return 0; }
  return 1;
}

static int opt_bad(lua_State *L, const char *key, const char *want) {
  return luaL_error(L, "bad option '%s' (%s expected, got %s)", key, want,
                    luaL_typename(L, -1));
}

double gr_opt_number(lua_State *L, int idx, const char *key, double def) {
  idx = lua_absindex(L, idx);
  if (!opt_get(L, idx, key)) return def;
  int ok;
  double v = lua_tonumberx(L, -1, &ok);
  if (!ok) opt_bad(L, key, "number");
  lua_pop(L, 1);
  return v;
}

int gr_opt_integer(lua_State *L, int idx, const char *key, int def) {
  idx = lua_absindex(L, idx);
  if (!opt_get(L, idx, key)) return def;
  int ok;
  lua_Integer v = lua_tointegerx(L, -1, &ok);
  if (!ok) opt_bad(L, key, "integer");
  lua_pop(L, 1);
  return (int)v;
}

int gr_opt_boolean(lua_State *L, int idx, const char *key, int def) {
  idx = lua_absindex(L, idx);
  if (!opt_get(L, idx, key)) return def;
  if (!lua_isboolean(L, -1)) opt_bad(L, key, "boolean");
  int v = lua_toboolean(L, -1);
  lua_pop(L, 1);
  return v;
}

/* The string stays valid while the option table is alive (it is one of its
 * values), so the pop is safe. */
const char *gr_opt_string(lua_State *L, int idx, const char *key, const char *def) {
  idx = lua_absindex(L, idx);
  if (!opt_get(L, idx, key)) return def;
  if (lua_type(L, -1) != LUA_TSTRING) opt_bad(L, key, "string");
  const char *s = lua_tostring(L, -1);
  lua_pop(L, 1);
  return s;
}

int gr_opt_vec(lua_State *L, int idx, const char *key, int n, double *out) {
  idx = lua_absindex(L, idx);
  if (!opt_get(L, idx, key)) return 0;
  if (lua_type(L, -1) == LUA_TNUMBER) {
    for (int i = 0; i < n; i++) out[i] = lua_tonumber(L, -1);
  } else if (lua_type(L, -1) == LUA_TTABLE) {
    if ((int)luaL_len(L, -1) != n)
      luaL_error(L, "bad option '%s' (%d numbers expected, got %d)", key, n, (int)luaL_len(L, -1));
    for (int i = 0; i < n; i++) {
      lua_geti(L, -1, i + 1);
      int ok;
      out[i] = lua_tonumberx(L, -1, &ok);
      if (!ok) luaL_error(L, "bad option '%s' (item %d is not a number)", key, i + 1);
      lua_pop(L, 1);
    }
  } else {
    opt_bad(L, key, "table of numbers");
  }
  lua_pop(L, 1);
  return 1;
}

/* ---- userdata boxes: one pointer each, NULL once closed ---- */
typedef struct box { void *p; } box;

#define BOX_TYPE(NAME, MT, TYPE, FREE)                                        \
  static int NAME##_gc(lua_State *L) {                                        \
    box *b = luaL_checkudata(L, 1, MT);                                       \
    if (b->p) FREE((TYPE *)b->p);                                             \
    b->p = NULL;                                                              \
    return 0;                                                                 \
  }                                                                           \
  TYPE *gr_check_##NAME(lua_State *L, int idx) {                              \
    box *b = luaL_checkudata(L, idx, MT);                                     \
    if (!b->p) luaL_argerror(L, idx, "object is closed");                     \
    return b->p;                                                              \
  }                                                                           \
  void gr_push_##NAME(lua_State *L, TYPE *p) {                                \
    box *b = lua_newuserdatauv(L, sizeof *b, 1);                              \
    b->p = p;                                                                 \
    luaL_setmetatable(L, MT);                                                 \
  }

BOX_TYPE(field, GR_MT_FIELD, gr_field, gr_field_free)
BOX_TYPE(mesh, GR_MT_MESH, gr_mesh, gr_mesh_free)
BOX_TYPE(rings, GR_MT_RINGS, gr_rings, gr_rings_free)
BOX_TYPE(layer, GR_MT_LAYER, gr_layer, gr_layer_free)

static int default_tostring(lua_State *L) {
  box *b = lua_touserdata(L, 1);
  lua_getmetatable(L, 1);
  lua_getfield(L, -1, "__name");
  lua_pushfstring(L, "%s: %p%s", lua_tostring(L, -1), (void *)b,
                  b && b->p ? "" : " (closed)");
  return 1;
}

static void new_type(lua_State *L, const char *name, lua_CFunction gc) {
  luaL_newmetatable(L, name); /* sets __name */
  lua_pushcfunction(L, gc);
  lua_setfield(L, -2, "__gc");
  lua_pushcfunction(L, gc);
  lua_setfield(L, -2, "__close");
  lua_pushcfunction(L, default_tostring);
  lua_setfield(L, -2, "__tostring");
  lua_newtable(L);
  lua_pushcfunction(L, gc);
  lua_setfield(L, -2, "close");
  lua_setfield(L, -2, "__index");
  lua_pop(L, 1);
}

void gr_register_types(lua_State *L) {
  new_type(L, GR_MT_FIELD, field_gc);
  new_type(L, GR_MT_MESH, mesh_gc);
  new_type(L, GR_MT_RINGS, rings_gc);
  new_type(L, GR_MT_LAYER, layer_gc);
}

void gr_add_methods(lua_State *L, const char *type, const luaL_Reg *methods) {
  luaL_getmetatable(L, type);
  lua_getfield(L, -1, "__index");
  for (const luaL_Reg *r = methods; r->name; r++) {
    lua_pushcfunction(L, r->func);
    if (r->name[0] == '_' && r->name[1] == '_')
      lua_setfield(L, -3, r->name); /* metamethod */
    else
      lua_setfield(L, -2, r->name);
  }
  lua_pop(L, 2);
}
