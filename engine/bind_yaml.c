/* bind_yaml.c: YAML to Lua values through libyaml. C only turns parser
 * events into Lua values; everything else (defaults, validation) is Lua's.
 * The parser lives in a userdata with __gc, so a Lua error midway (e.g. out
 * of memory) never leaks it; the previous event is deleted before the next.
 *   gradus.yaml.decode(text [, name]) -> value of the first document
 *   gradus.yaml.load(path)            -> value of the first document
 *   gradus.yaml.load_all(path)        -> { documents... }
 *   gradus.yaml.load(path, {marks = true}) (decode: third argument)
 *                                     -> value, marks: marks[mapping][key] =
 *                                        "LINE:COL" of the key, so that a
 *                                        checker can point at an unknown key
 * Scalars: plain null/~/empty -> nil (absent key), true/false/yes/no/on/off
 * -> boolean, integers and floats (.inf, .nan) -> numbers; quoted or tagged
 * !!str -> string. Anchors and aliases are supported; duplicate keys are an
 * error. Errors: "NAME:LINE:COL: problem (context)". */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <yaml.h>
#include "bind.h"

#define YAML_MT "gradus.yaml.parser"
#define MAX_DEPTH 200

typedef struct yparser {
  yaml_parser_t parser;
  yaml_event_t event;
  int have_parser, have_event;
  const char *name; /* for messages; kept alive on the Lua stack */
  int anchors;      /* stack index of the anchors table */
  int marks;        /* stack index of the marks table, 0 = not wanted */
} yparser;

static int yp_gc(lua_State *L) {
  yparser *p = luaL_checkudata(L, 1, YAML_MT);
  if (p->have_event) yaml_event_delete(&p->event);
  if (p->have_parser) yaml_parser_delete(&p->parser);
  p->have_event = p->have_parser = 0;
  return 0;
}

static int yp_next(lua_State *L, yparser *p) {
  if (p->have_event) {
    yaml_event_delete(&p->event);
    p->have_event = 0;
  }
  if (!yaml_parser_parse(&p->parser, &p->event)) {
    const char *problem = p->parser.problem ? p->parser.problem : "syntax error";
    size_t line = p->parser.problem_mark.line + 1, col = p->parser.problem_mark.column + 1;
    if (p->parser.context)
      return luaL_error(L, "%s:%d:%d: %s (%s)", p->name, (int)line, (int)col, problem,
                        p->parser.context);
    return luaL_error(L, "%s:%d:%d: %s", p->name, (int)line, (int)col, problem);
  }
  p->have_event = 1;
  return p->event.type;
}

static int ieq(const char *a, const char *b) { return strcasecmp(a, b) == 0; }

/* Push the Lua value of a scalar event. */
static void push_scalar(lua_State *L, yparser *p) {
  const char *s = (const char *)p->event.data.scalar.value;
  size_t n = p->event.data.scalar.length;
  const char *tag = (const char *)p->event.data.scalar.tag;
  if (p->event.data.scalar.style != YAML_PLAIN_SCALAR_STYLE ||
      (tag && strcmp(tag, YAML_STR_TAG) == 0)) {
    lua_pushlstring(L, s, n);
    return;
  }
  if (n == 0 || strcmp(s, "~") == 0 || ieq(s, "null")) { lua_pushnil(L); return; }
  if (ieq(s, "true") || ieq(s, "yes") || ieq(s, "on")) { lua_pushboolean(L, 1); return; }
  if (ieq(s, "false") || ieq(s, "no") || ieq(s, "off")) { lua_pushboolean(L, 0); return; }
  if (ieq(s, ".inf") || ieq(s, "+.inf")) { lua_pushnumber(L, HUGE_VAL); return; }
  if (ieq(s, "-.inf")) { lua_pushnumber(L, -HUGE_VAL); return; }
  if (ieq(s, ".nan")) { lua_pushnumber(L, NAN); return; }
  if (strlen(s) == n && lua_stringtonumber(L, s) != 0) return; /* pushed the number */
  lua_pushlstring(L, s, n);
}

static void set_anchor(lua_State *L, yparser *p, const unsigned char *anchor) {
  if (!anchor) return;
  lua_pushvalue(L, -1);
  lua_setfield(L, p->anchors, (const char *)anchor);
}

/* marks[map][key] = "LINE:COL", the key on top of the stack. */
static void mark_key(lua_State *L, yparser *p, int map, int line, int col) {
  lua_pushvalue(L, map);
  lua_rawget(L, p->marks);
  lua_pushvalue(L, -2);
  lua_pushfstring(L, "%d:%d", line, col);
  lua_rawset(L, -3);
  lua_pop(L, 1);
}

/* Parse the node starting at the current event; push its value. */
/* A merge key ("<<") takes a mapping or a sequence of mappings; anything else
 * (a scalar such as `<<: abc`) is refused here, before the merge walks it. */
static void check_merge(lua_State *L, const char *name, int line, int col) {
  int ok = lua_type(L, -1) == LUA_TTABLE;
  lua_Integer n = ok ? (lua_Integer)lua_rawlen(L, -1) : 0;
  for (lua_Integer i = 1; ok && i <= n; i++) {
    ok = lua_rawgeti(L, -1, i) == LUA_TTABLE;
    lua_pop(L, 1);
  }
  if (!ok)
    luaL_error(L, "%s:%d:%d: merge key '<<' needs a mapping or a sequence of mappings, got a%s %s", name, line,
               col, lua_type(L, -1) == LUA_TTABLE ? "" : "", lua_type(L, -1) == LUA_TTABLE ? "sequence with a scalar" : luaL_typename(L, -1));
}

static void parse_node(lua_State *L, yparser *p, int depth) {
  if (depth > MAX_DEPTH)
    luaL_error(L, "%s:%d: nesting deeper than %d", p->name,
               (int)p->event.start_mark.line + 1, MAX_DEPTH);
  luaL_checkstack(L, 8, "YAML nesting");
  switch (p->event.type) {
  case YAML_SCALAR_EVENT: {
    const unsigned char *anchor = p->event.data.scalar.anchor;
    push_scalar(L, p);
    set_anchor(L, p, anchor);
    return;
  }
  case YAML_ALIAS_EVENT: {
    const char *a = (const char *)p->event.data.alias.anchor;
    if (lua_getfield(L, p->anchors, a) == LUA_TNIL)
      luaL_error(L, "%s:%d:%d: unknown alias '*%s'", p->name,
                 (int)p->event.start_mark.line + 1, (int)p->event.start_mark.column + 1, a);
    return;
  }
  case YAML_SEQUENCE_START_EVENT: {
    lua_newtable(L);
    set_anchor(L, p, p->event.data.sequence_start.anchor);
    lua_Integer i = 1;
    while (yp_next(L, p) != YAML_SEQUENCE_END_EVENT) {
      parse_node(L, p, depth + 1);
      lua_rawseti(L, -2, i++);
    }
    return;
  }
  case YAML_MAPPING_START_EVENT: {
    lua_newtable(L);
    set_anchor(L, p, p->event.data.mapping_start.anchor);
    int map = lua_gettop(L);
    lua_newtable(L); /* merge sources ("<<" keys), applied at the end */
    int merges = map + 1;
    if (p->marks) { /* marks[map] = { key = "LINE:COL" } */
      lua_pushvalue(L, map);
      lua_newtable(L);
      lua_rawset(L, p->marks);
    }
    lua_Integer nmerge = 0;
    while (yp_next(L, p) != YAML_MAPPING_END_EVENT) {
      int line = (int)p->event.start_mark.line + 1, col = (int)p->event.start_mark.column + 1;
      parse_node(L, p, depth + 1); /* key */
      if (lua_isnil(L, -1))
        luaL_error(L, "%s:%d:%d: null mapping key", p->name, line, col);
      if (lua_type(L, -1) == LUA_TSTRING && strcmp(lua_tostring(L, -1), "<<") == 0) {
        lua_pop(L, 1);
        yp_next(L, p);
        int vline = (int)p->event.start_mark.line + 1, vcol = (int)p->event.start_mark.column + 1;
        parse_node(L, p, depth + 1);
        check_merge(L, p->name, vline, vcol);
        lua_rawseti(L, merges, ++nmerge);
        continue;
      }
      lua_pushvalue(L, -1);
      if (lua_rawget(L, map) != LUA_TNIL)
        luaL_error(L, "%s:%d:%d: duplicate key '%s'", p->name, line, col,
                   luaL_tolstring(L, -2, NULL));
      lua_pop(L, 1);
      if (p->marks) mark_key(L, p, map, line, col);
      yp_next(L, p);
      parse_node(L, p, depth + 1); /* value */
      lua_rawset(L, map);
    }
    /* explicit keys win over merged ones; a merge value may be a mapping or a
     * sequence of mappings (earlier ones win) */
    for (lua_Integer i = 1; i <= nmerge; i++) {
      lua_rawgeti(L, merges, i);
      int src = lua_gettop(L);
      lua_Integer nsub = luaL_len(L, src);
      for (lua_Integer j = 0; j <= nsub; j++) {
        if (j == 0) lua_pushvalue(L, src);
        else lua_rawgeti(L, src, j);
        if (lua_type(L, -1) == LUA_TTABLE) {
          lua_pushnil(L);
          while (lua_next(L, -2)) {
            lua_pushvalue(L, -2);
            if (lua_rawget(L, map) == LUA_TNIL && !(j == 0 && nsub > 0 && lua_isinteger(L, -3))) {
              lua_pop(L, 1);
              lua_pushvalue(L, -2);
              lua_insert(L, -2);
              lua_rawset(L, map);
            } else {
              lua_pop(L, 2);
            }
          }
        }
        lua_pop(L, 1);
      }
      lua_pop(L, 1);
    }
    lua_pop(L, 1); /* merges */
    return;
  }
  default:
    luaL_error(L, "%s:%d:%d: unexpected YAML event", p->name,
               (int)p->event.start_mark.line + 1, (int)p->event.start_mark.column + 1);
  }
}

/* Decode text (stack index 1) named `name`; all = 1 returns every document. */
static int decode(lua_State *L, const char *text, size_t len, const char *name, int all, int marks) {
  yparser *p = lua_newuserdatauv(L, sizeof *p, 0);
  memset(p, 0, sizeof *p);
  luaL_setmetatable(L, YAML_MT);
  if (!yaml_parser_initialize(&p->parser)) return luaL_error(L, "%s: cannot start YAML parser", name);
  p->have_parser = 1;
  p->name = name;
  if (marks) {
    lua_newtable(L);
    p->marks = lua_gettop(L);
  }
  yaml_parser_set_input_string(&p->parser, (const unsigned char *)text, len);
  lua_newtable(L); /* documents */
  int docs = lua_gettop(L);
  lua_Integer ndocs = 0;
  for (;;) {
    int t = yp_next(L, p);
    if (t == YAML_STREAM_END_EVENT) break;
    if (t != YAML_DOCUMENT_START_EVENT) continue;
    lua_newtable(L); /* anchors of this document */
    p->anchors = lua_gettop(L);
    yp_next(L, p);
    if (p->event.type == YAML_DOCUMENT_END_EVENT) {
      lua_pushnil(L);
    } else {
      parse_node(L, p, 0);
      yp_next(L, p); /* document end */
    }
    lua_rawseti(L, docs, ++ndocs);
    lua_pop(L, 1); /* anchors */
    if (!all) break;
  }
  if (p->have_event) yaml_event_delete(&p->event);
  yaml_parser_delete(&p->parser);
  p->have_event = p->have_parser = 0;
  if (all) {
    if (!p->marks) return 1;
    lua_pushvalue(L, p->marks);
    return 2;
  }
  lua_rawgeti(L, docs, 1);
  if (!p->marks) return 1;
  lua_pushvalue(L, p->marks);
  return 2;
}

/* opts.marks at stack index idx (a table, or none) */
static int want_marks(lua_State *L, int idx) {
  if (lua_isnoneornil(L, idx)) return 0;
  luaL_checktype(L, idx, LUA_TTABLE);
  return gr_opt_boolean(L, idx, "marks", 0);
}

static int y_decode(lua_State *L) {
  size_t len;
  const char *text = luaL_checklstring(L, 1, &len);
  const char *name = luaL_optstring(L, 2, "<string>");
  return decode(L, text, len, name, 0, want_marks(L, 3));
}

static int load_file(lua_State *L, int all) {
  const char *path = luaL_checkstring(L, 1);
  int marks = want_marks(L, 2);
  gr_lua_guard(L, path, "r");
  FILE *f = fopen(path, "rb");
  if (!f) return luaL_error(L, "cannot read YAML file %s: %s", path, strerror(errno));
  luaL_Buffer b;
  luaL_buffinit(L, &b);
  char buf[8192];
  size_t n;
  while ((n = fread(buf, 1, sizeof buf, f)) > 0) luaL_addlstring(&b, buf, n);
  int bad = ferror(f);
  fclose(f);
  if (bad) return luaL_error(L, "cannot read YAML file %s", path);
  luaL_pushresult(&b);
  size_t len;
  const char *text = lua_tolstring(L, -1, &len);
  return decode(L, text, len, path, all, marks);
}

static int y_load(lua_State *L) { return load_file(L, 0); }
static int y_load_all(lua_State *L) { return load_file(L, 1); }

static const luaL_Reg yaml_fns[] = {
    {"decode", y_decode}, {"load", y_load}, {"load_all", y_load_all}, {NULL, NULL}};

int gr_open_yaml(lua_State *L) {
  luaL_newmetatable(L, YAML_MT);
  lua_pushcfunction(L, yp_gc);
  lua_setfield(L, -2, "__gc");
  lua_pop(L, 1);
  luaL_newlib(L, yaml_fns);
  lua_setfield(L, -2, "yaml");
  return 0;
}
