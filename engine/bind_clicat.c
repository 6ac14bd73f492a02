/* bind_clicat.c: gradus.cli.cat (clicat.h). */
#include "bind.h"
#include "clicat.h"
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
  lua_pushinteger(L, info.layers);
  lua_setfield(L, -2, "layers");
  lua_pushinteger(L, info.first);
  lua_setfield(L, -2, "first");
  lua_pushinteger(L, info.last);
  lua_setfield(L, -2, "last");
  lua_pushnumber(L, info.layer_mm);
  lua_setfield(L, -2, "layer_mm");
  return 1;
}

int gr_open_clicat(lua_State *L) {
  lua_getfield(L, -1, "cli");
  lua_pushcfunction(L, l_cat);
  lua_setfield(L, -2, "cat");
  lua_pop(L, 1);
  return 0;
}
