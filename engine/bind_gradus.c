/* bind_gradus.c: the `gradus` Lua module. luaopen_gradus builds the module
 * table from every primitive's binding, then loads the Lua side
 * (lua/gradus/lib.lua: params, recipes helpers, policy), found relative to
 * the shared object or executable that holds this code (<root>/build/x ->
 * <root>/lua), so `require "gradus"` works from a stock lua5.4 too. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <libgen.h>
#include <unistd.h>
#include <limits.h>
#include <stdlib.h>
#include <string.h>
#include "bind.h"
#include "bind_ovf.h"
#include "version.h"

/* Where the tree is: two levels above the file holding this function. */
static int find_root(char *out, size_t n) {
  Dl_info info;
  char buf[PATH_MAX], real[PATH_MAX];
  if (!dladdr((void *)find_root, &info) || !info.dli_fname) return 0;
  snprintf(buf, sizeof buf, "%s", info.dli_fname);
  if (!realpath(buf, real)) {
    /* the executable itself may be found through /proc */
    ssize_t k = readlink("/proc/self/exe", real, sizeof real - 1);
    if (k <= 0) return 0;
    real[k] = 0;
  }
  char *d = dirname(real); /* .../build */
  snprintf(buf, sizeof buf, "%s", d);
  d = dirname(buf); /* root */
  snprintf(out, n, "%s", d);
  return 1;
}

/* gradus.clock() -> monotonic wall-clock seconds. */
static int g_clock(lua_State *L) {
  lua_pushnumber(L, gr_now());
  return 1;
}

int luaopen_gradus(lua_State *L) {
  lua_newtable(L);
  lua_pushcfunction(L, g_clock);
  lua_setfield(L, -2, "clock");
  gr_register_types(L);
  gr_open_field(L);
  gr_open_mesh(L);
  gr_open_distance(L);
  gr_open_slice(L);
  gr_open_hatch(L);
  gr_open_io(L);
  gr_open_clicat(L);
  gr_open_ovf(L);
  gr_open_yaml(L);
  gr_open_fs(L);
  gr_open_place(L);
  gr_open_view(L);
  gr_open_density(L);
  lua_pushstring(L, GRADUS_VERSION);
  lua_setfield(L, -2, "version");
  char root[PATH_MAX];
  if (find_root(root, sizeof root)) {
    lua_pushstring(L, root);
    lua_setfield(L, -2, "root");
    /* put <root>/lua first on package.path */
    lua_getglobal(L, "package");
    lua_pushfstring(L, "%s/lua/?.lua;%s/lua/?/init.lua;", root, root);
    lua_getfield(L, -2, "path");
    lua_concat(L, 2);
    lua_setfield(L, -2, "path");
    lua_pop(L, 1);
  }
  /* register before loading the Lua side, which extends this table */
  lua_getglobal(L, "package");
  lua_getfield(L, -1, "loaded");
  lua_pushvalue(L, -3);
  lua_setfield(L, -2, "gradus");
  lua_pop(L, 2);
  lua_getglobal(L, "require");
  lua_pushstring(L, "gradus.lib");
  lua_call(L, 1, 0);
  return 1;
}
