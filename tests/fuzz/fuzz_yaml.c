/* libFuzzer harness: the YAML loader (engine/bind_yaml.c, libyaml events to
 * Lua values, anchors, aliases and merge keys). Each input is decoded in a
 * fresh Lua state inside a protected call: a Lua error is a normal outcome. */
#include <lauxlib.h>
#include <lua.h>
#include <lualib.h>
#include <stdint.h>
#include "bind.h"

static int decode(lua_State *L) {
  size_t n;
  const char *s = lua_tolstring(L, 1, &n);
  lua_newtable(L);
  gr_open_yaml(L);
  lua_getfield(L, -1, "yaml");
  lua_getfield(L, -1, "decode");
  lua_pushlstring(L, s, n);
  lua_pushstring(L, "fuzz.yaml");
  lua_call(L, 2, 1);
  return 1;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  if (size > 65536) return 0;
  lua_State *L = luaL_newstate();
  if (!L) return 0;
  luaL_openlibs(L);
  lua_pushcfunction(L, decode);
  lua_pushlstring(L, (const char *)data, size);
  lua_pcall(L, 1, 1, 0);
  lua_close(L);
  return 0;
}
