/* bind_fs.c: the file-system and process facts the Lua side needs to guard
 * outputs (lua/gradus/outputs.lua) and that Lua's io/os libraries lack:
 *   gradus.fs.kind(path) -> "file"|"directory"|"symlink"|"fifo"|"char"|"block"|"socket" or nil (absent)
 *   gradus.fs.refusal(path) -> why path may not be replaced by an output ("a FIFO", ...) or nil
 *   gradus.fs.pid() -> this process's id
 *   gradus.fs.alive(pid) -> whether a process with that id runs
 *   gradus.fs.list(dir) -> array of names (without . and ..), or nil, message
 *   gradus.fs.mtime(path) -> modification time (Unix seconds) or nil
 *   gradus.fs.interrupted() -> 0, 1 (Ctrl-C requested) or 2 (requested and reported)
 *   gradus.fs.clear_interrupt()
 *   gradus.fs.realpath(path) -> the absolute path without symbolic links, . or .., or nil, message
 * and gr_lua_stage() / gr_lua_guard(), through which C readers and writers
 * ask the job's output transaction where to write and the sandbox
 * (lua/gradus/sandbox.lua) whether they may. */
#include <dirent.h>
#include <limits.h>
#include <stdlib.h>
#include <errno.h>
#include <signal.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include "bind.h"
#include "interrupt.h"

static int f_kind(lua_State *L) {
  struct stat st;
  if (lstat(luaL_checkstring(L, 1), &st) != 0) return 0;
  mode_t m = st.st_mode;
  lua_pushstring(L, S_ISREG(m) ? "file" : S_ISDIR(m) ? "directory" : S_ISLNK(m) ? "symlink"
                    : S_ISFIFO(m) ? "fifo" : S_ISCHR(m) ? "char" : S_ISBLK(m) ? "block" : "socket");
  return 1;
}

static int f_refusal(lua_State *L) {
  const char *why = gr_output_refusal(luaL_checkstring(L, 1));
  if (!why) return 0;
  lua_pushstring(L, why);
  return 1;
}

static int f_pid(lua_State *L) {
  lua_pushinteger(L, (lua_Integer)getpid());
  return 1;
}

static int f_alive(lua_State *L) {
  lua_Integer pid = luaL_checkinteger(L, 1);
  lua_pushboolean(L, pid > 0 && pid <= 0x7fffffff && (kill((pid_t)pid, 0) == 0 || errno == EPERM));
  return 1;
}

static int f_list(lua_State *L) {
  const char *dir = luaL_checkstring(L, 1);
  DIR *d = opendir(dir);
  if (!d) {
    lua_pushnil(L);
    lua_pushfstring(L, "cannot list %s: %s", dir, strerror(errno));
    return 2;
  }
  lua_newtable(L);
  lua_Integer n = 0;
  struct dirent *de;
  while ((de = readdir(d))) {
    if (!strcmp(de->d_name, ".") || !strcmp(de->d_name, "..")) continue;
    lua_pushstring(L, de->d_name);
    lua_rawseti(L, -2, ++n);
  }
  closedir(d);
  return 1;
}

static int f_mtime(lua_State *L) {
  struct stat st;
  if (lstat(luaL_checkstring(L, 1), &st) != 0) return 0;
  lua_pushinteger(L, (lua_Integer)st.st_mtime);
  return 1;
}

static int f_interrupted(lua_State *L) {
  lua_pushinteger(L, gr_interrupted());
  return 1;
}

static int f_clear_interrupt(lua_State *L) {
  (void)L;
  gr_interrupt_clear();
  return 0;
}

static int f_realpath(lua_State *L) {
  const char *p = luaL_checkstring(L, 1);
  char buf[PATH_MAX];
  if (!realpath(p, buf)) {
    lua_pushnil(L);
    lua_pushfstring(L, "%s: %s", p, strerror(errno));
    return 2;
  }
  lua_pushstring(L, buf);
  return 1;
}

/* package.loaded["gradus.outputs"][fn] pushed, or nothing and 0 */
static int outputs_fn(lua_State *L, const char *fn) {
  luaL_getsubtable(L, LUA_REGISTRYINDEX, LUA_LOADED_TABLE);
  lua_getfield(L, -1, "gradus.outputs");
  lua_remove(L, -2);
  if (lua_istable(L, -1) && lua_getfield(L, -1, fn) == LUA_TFUNCTION) {
    lua_remove(L, -2);
    return 1;
  }
  lua_pop(L, lua_istable(L, -1) ? 2 : 1);
  return 0;
}

void gr_lua_guard(lua_State *L, const char *path, const char *mode) {
  if (!outputs_fn(L, "guard")) return;
  lua_pushstring(L, path);
  lua_pushstring(L, mode);
  lua_call(L, 2, 0);
}

const char *gr_lua_stage(lua_State *L, const char *path) {
  if (!outputs_fn(L, "stage")) {
    lua_pushstring(L, path);
    return lua_tostring(L, -1);
  }
  lua_pushstring(L, path);
  lua_call(L, 1, 1);
  return luaL_checkstring(L, -1);
}

static const luaL_Reg fs_fns[] = {
    {"kind", f_kind},   {"refusal", f_refusal}, {"pid", f_pid},
    {"alive", f_alive}, {"list", f_list},       {"mtime", f_mtime},
    {"interrupted", f_interrupted}, {"clear_interrupt", f_clear_interrupt}, {"realpath", f_realpath}, {NULL, NULL}};

int gr_open_fs(lua_State *L) {
  luaL_newlib(L, fs_fns);
  lua_setfield(L, -2, "fs");
  return 0;
}
