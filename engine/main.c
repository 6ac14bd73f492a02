/* main.c: the `gradus` executable. It opens a Lua state with the standard
 * libraries and the gradus module, adds the terminal functions the REPL and
 * progress reports need (readline, isatty), and hands the command line to
 * lua/gradus/host.lua inside one protected call (as lua.c does). */
#include <lauxlib.h>
#include <lua.h>
#include <lualib.h>
#include <readline/history.h>
#include <readline/readline.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

int luaopen_gradus(lua_State *L);

/* term.readline(prompt) -> line or nil at end of input. Uses GNU readline on
 * a terminal, plain fgets otherwise (no prompt echo when input is piped). */
static int t_readline(lua_State *L) {
  const char *prompt = luaL_optstring(L, 1, "> ");
  if (isatty(0)) {
    char *s = readline(prompt);
    if (!s) return 0;
    lua_pushstring(L, s);
    free(s);
    return 1;
  }
  luaL_Buffer b;
  luaL_buffinit(L, &b);
  int any = 0, c;
  while ((c = getchar()) != EOF) {
    any = 1;
    if (c == '\n') break;
    luaL_addchar(&b, (char)c);
  }
  if (!any) return 0;
  luaL_pushresult(&b);
  return 1;
}

static int t_add_history(lua_State *L) {
  const char *s = luaL_checkstring(L, 1);
  if (isatty(0) && *s) add_history(s);
  return 0;
}

static int t_isatty(lua_State *L) {
  lua_pushboolean(L, isatty((int)luaL_checkinteger(L, 1)));
  return 1;
}

static int t_read_history(lua_State *L) {
  if (isatty(0)) read_history(luaL_checkstring(L, 1));
  return 0;
}

static int t_write_history(lua_State *L) {
  if (isatty(0)) write_history(luaL_checkstring(L, 1));
  return 0;
}

static const luaL_Reg term_fns[] = {
    {"readline", t_readline},           {"add_history", t_add_history},
    {"isatty", t_isatty},               {"read_history", t_read_history},
    {"write_history", t_write_history}, {NULL, NULL}};

/* Message handler: keep the error value, append a traceback (host.lua
 * shortens it to the recipe's frames). */
static int msghandler(lua_State *L) {
  const char *msg = lua_tostring(L, 1);
  if (!msg) {
    if (luaL_callmeta(L, 1, "__tostring") && lua_type(L, -1) == LUA_TSTRING) return 1;
    msg = lua_pushfstring(L, "(error object is a %s value)", luaL_typename(L, 1));
  }
  luaL_traceback(L, L, msg, 1);
  return 1;
}

static int pmain(lua_State *L) {
  int argc = (int)lua_tointeger(L, 1);
  char **argv = lua_touserdata(L, 2);
  luaL_openlibs(L);
  luaL_requiref(L, "gradus", luaopen_gradus, 0);
  luaL_newlib(L, term_fns);
  lua_setfield(L, -2, "term");
  lua_pop(L, 1);
  lua_getglobal(L, "require");
  lua_pushstring(L, "gradus.host");
  lua_call(L, 1, 1);
  lua_getfield(L, -1, "main");
  lua_newtable(L);
  for (int i = 1; i < argc; i++) {
    lua_pushstring(L, argv[i]);
    lua_rawseti(L, -2, i);
  }
  lua_call(L, 1, 1);
  return 1;
}

int main(int argc, char **argv) {
  lua_State *L = luaL_newstate();
  if (!L) {
    fprintf(stderr, "gradus: cannot create Lua state: not enough memory\n");
    return 1;
  }
  signal(SIGPIPE, SIG_IGN);
  lua_pushcfunction(L, msghandler);
  lua_pushcfunction(L, pmain);
  lua_pushinteger(L, argc);
  lua_pushlightuserdata(L, argv);
  int st = lua_pcall(L, 2, 1, 1);
  int rc;
  if (st != LUA_OK) {
    fprintf(stderr, "gradus: %s\n", lua_tostring(L, -1));
    rc = 1;
  } else {
    rc = (int)lua_tointeger(L, -1);
  }
  lua_close(L);
  return rc;
}
