/* main.c: the `gradus` executable. It opens a Lua state with the standard
 * libraries and the gradus module, adds the terminal functions the REPL and
 * progress reports need (readline, isatty), and hands the command line to
 * lua/gradus/host.lua inside one protected call (as lua.c does).
 * It also owns what only the process can do: the Lua allocator with its
 * memory cap and the instruction/time hook (the --sandbox limits), and the
 * Ctrl-C handler that asks the job to stop (engine/interrupt.h). */
#include <lauxlib.h>
#include <lua.h>
#include <lualib.h>
#include <malloc.h>
#include <readline/history.h>
#include <readline/readline.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>
#include "interrupt.h"

int luaopen_gradus(lua_State *L);

/* The Lua heap's account and the sandbox limits; the allocator's user data,
 * so that the hook finds it with lua_getallocf. */
#define HOOK_EVERY 1000 /* instructions between two looks at the limits */
typedef struct host_limits {
  size_t used, cap;     /* Lua heap bytes in use; cap 0 = no limit */
  long long steps;      /* instructions counted (in HOOK_EVERY steps) */
  long long max_steps;  /* 0 = no limit */
  double deadline;      /* CLOCK_MONOTONIC seconds; 0 = no limit */
  char library[4096];   /* sources under this prefix are gradus's own code */
  char tripped[160];    /* the limit reached, "" while none */
} host_limits;

static void *h_alloc(void *ud, void *ptr, size_t osize, size_t nsize) {
  host_limits *m = ud;
  if (!ptr) osize = 0;
  if (nsize == 0) {
    free(ptr);
    m->used -= osize;
    return NULL;
  }
  if (m->cap && nsize > osize && m->used - osize + nsize > m->cap) {
    if (!m->tripped[0]) snprintf(m->tripped, sizeof m->tripped, "memory limit of %zu MiB reached", m->cap >> 20);
    return NULL;
  }
  void *p = realloc(ptr, nsize);
  if (p) m->used = m->used - osize + nsize;
  return p;
}

static double now_s(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

/* Is the running function gradus's own Lua code (or C)? Limits stop the
 * recipe, not the host's clean-up after it. */
static int in_library(lua_State *L, const host_limits *m) {
  lua_Debug ar;
  if (!lua_getstack(L, 0, &ar) || !lua_getinfo(L, "S", &ar)) return 1;
  if (ar.source[0] != '@') return ar.source[0] == '=' && !strcmp(ar.source, "=[C]");
  return m->library[0] && !strncmp(ar.source + 1, m->library, strlen(m->library));
}

static void h_hook(lua_State *L, lua_Debug *ar);

static void set_hook(lua_State *L, const host_limits *m) {
  if (m->max_steps || m->deadline > 0) lua_sethook(L, h_hook, LUA_MASKCOUNT, HOOK_EVERY);
  else lua_sethook(L, NULL, 0, 0);
}

/* Ctrl-C first (raised once, anywhere), then the sandbox limits: once one is
 * reached every later look raises again while the recipe's code runs, so a
 * pcall in the recipe cannot outlast it. */
static void h_hook(lua_State *L, lua_Debug *ar) {
  void *ud;
  lua_getallocf(L, &ud);
  host_limits *m = ud;
  char where[300] = ""; /* the line running now: where the recipe stopped */
  if (lua_getinfo(L, "Sl", ar) && ar->currentline > 0)
    snprintf(where, sizeof where, "%s:%d: ", ar->short_src, ar->currentline);
  if (gr_interrupted() == 1) {
    gr_interrupt_reported();
    set_hook(L, m);
    luaL_error(L, "%sinterrupted (Ctrl-C)", where);
  }
  if (ar->event != LUA_HOOKCOUNT) return;
  m->steps += HOOK_EVERY;
  if (!m->tripped[0] && m->max_steps && m->steps > m->max_steps)
    snprintf(m->tripped, sizeof m->tripped, "instruction limit of %lld reached", m->max_steps);
  if (!m->tripped[0] && m->deadline > 0 && now_s() > m->deadline)
    snprintf(m->tripped, sizeof m->tripped, "time limit reached");
  if (m->tripped[0] && !in_library(L, m)) luaL_error(L, "%ssandbox: %s", where, m->tripped);
}

/* term.limits{memory = MiB, instructions = n, seconds = s, library = prefix}:
 * set once by the host for --sandbox (the recipe never sees term). */
static int t_limits(lua_State *L) {
  luaL_checktype(L, 1, LUA_TTABLE);
  void *ud;
  lua_getallocf(L, &ud);
  host_limits *m = ud;
  lua_getfield(L, 1, "memory");
  lua_getfield(L, 1, "instructions");
  lua_getfield(L, 1, "seconds");
  lua_getfield(L, 1, "library");
  double mib = luaL_optnumber(L, -4, 0), secs = luaL_optnumber(L, -2, 0);
  m->cap = mib > 0 ? (size_t)(mib * 1048576.0) : 0;
  if (m->cap && m->cap < m->used + ((size_t)8 << 20)) m->cap = m->used + ((size_t)8 << 20);
  m->max_steps = (long long)luaL_optnumber(L, -3, 0);
  m->deadline = secs > 0 ? now_s() + secs : 0;
  snprintf(m->library, sizeof m->library, "%s", luaL_optstring(L, -1, ""));
  m->tripped[0] = 0;
  m->steps = 0;
  set_hook(L, m);
  return 0;
}

/* term.limit_reached() -> the sandbox limit reached ("memory limit of ...") or nil */
static int t_limit_reached(lua_State *L) {
  void *ud;
  lua_getallocf(L, &ud);
  const host_limits *m = ud;
  if (!m->tripped[0]) return 0;
  lua_pushstring(L, m->tripped);
  return 1;
}

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
    {"write_history", t_write_history}, {"limits", t_limits},
    {"limit_reached", t_limit_reached}, {NULL, NULL}};

static int on_panic(lua_State *L) {
  const char *msg = lua_tostring(L, -1);
  fprintf(stderr, "gradus: unprotected Lua error: %s\n", msg ? msg : "(not a string)");
  return 0; /* abort */
}

/* The state the SIGINT handler stops (as lua.c keeps one). */
static lua_State *signal_state;

/* First Ctrl-C: ask the job to stop (the layer writer and the Lua hook look
 * at the flag); a second one ends the process at once. */
static void on_sigint(int sig) {
  signal(sig, SIG_DFL);
  gr_interrupt_request();
  lua_sethook(signal_state, h_hook, LUA_MASKCALL | LUA_MASKRET | LUA_MASKLINE | LUA_MASKCOUNT, 1);
}

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

/* Each template layer allocates its slice grid's scratch (about 0.5 MB at
 * the defaults) and frees it; by default glibc hands such blocks back to
 * the kernel between layers (mmap, or trimming the heap's top), and every
 * layer faults the pages in again, zeroed. Kept up to these sizes, they
 * are reused: on an 8 x 8 x 8 continuously graded part, 150,000 minor page
 * faults became 68,000 and system time 0.43 s became 0.15 s (peak RSS +17 MB). */
static void malloc_keep(void) {
  mallopt(M_MMAP_THRESHOLD, 16 << 20);
  mallopt(M_TRIM_THRESHOLD, 64 << 20);
}

int main(int argc, char **argv) {
  malloc_keep();
  host_limits lim; /* outlives the state: closed below */
  memset(&lim, 0, sizeof lim);
  lua_State *L = lua_newstate(h_alloc, &lim);
  if (L) lua_atpanic(L, on_panic);
  if (!L) {
    fprintf(stderr, "gradus: cannot create Lua state: not enough memory\n");
    return 1;
  }
  signal(SIGPIPE, SIG_IGN);
  signal_state = L;
  signal(SIGINT, on_sigint);
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
