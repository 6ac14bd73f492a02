/* bind.h: what the Lua binding files share. Only bind_*.c and main.c include
 * lua.h; the engine core never calls Lua.
 *
 * Conventions (after Lua's own liolib/lstrlib):
 *  - each bind_<name>.c has one exported gr_open_<name>(L), which adds its
 *    functions and sub-tables to the module table on the top of the stack,
 *    creates its metatables, and leaves the stack as it found it;
 *  - every big object lives in C, owned by exactly one userdata; the userdata
 *    is created before the object it will own; __gc and __close share one
 *    function; methods via __index; __tostring gives counts and bounds;
 *  - misuse raises (luaL_argcheck / luaL_argerror / gr_lua_error) with the
 *    parameter and its value: "bad argument #2 to 'hatch' (spacing must be
 *    > 0, got -0.05)"; the host prefixes the recipe's file:line;
 *  - option tables: gr_opt_number(L, idx, "spacing", default) and friends
 *    raise "bad option 'spacing' (number expected, got string)".
 */
#ifndef GR_BIND_H
#define GR_BIND_H
#include <lauxlib.h>
#include <lua.h>
#include "common.h"
#include "field.h"
#include "mesh.h"
#include "paths.h"

#define GR_MT_FIELD "gradus.field"
#define GR_MT_MESH "gradus.mesh"
#define GR_MT_RINGS "gradus.rings"
#define GR_MT_LAYER "gradus.layer"

/* Raise a Lua error with e->msg (never returns). */
int gr_lua_error(lua_State *L, const gr_err *e);
/* t[k] = v for the table on top of the stack. */
static inline void gr_lua_setnum(lua_State *L, const char *k, double v) { lua_pushnumber(L, v); lua_setfield(L, -2, k); }
static inline void gr_lua_setint(lua_State *L, const char *k, lua_Integer v) { lua_pushinteger(L, v); lua_setfield(L, -2, k); }

/* Option-table readers: idx is the table (may be absent/nil: default). */
double gr_opt_number(lua_State *L, int idx, const char *key, double def);
int gr_opt_integer(lua_State *L, int idx, const char *key, int def);
int gr_opt_boolean(lua_State *L, int idx, const char *key, int def);
const char *gr_opt_string(lua_State *L, int idx, const char *key, const char *def);
/* Read n numbers from key = {a, b, c} (or a single number repeated). Returns
 * 1 if present, 0 if absent (out untouched). */
int gr_opt_vec(lua_State *L, int idx, const char *key, int n, double *out);

/* The four userdata types (field, mesh, rings, layer) are created in
 * bind.c with __gc/__close, __name and a default __tostring. Each primitive's
 * binding adds its methods to a type with gr_add_methods (a "__tostring" entry
 * replaces the default one). */
void gr_register_types(lua_State *L);
void gr_add_methods(lua_State *L, const char *type, const luaL_Reg *methods);

/* Typed userdata access. check_* raise on a wrong type; push_* take
 * ownership of the object (one reference for fields). */
gr_field *gr_check_field(lua_State *L, int idx);
/* Accept a field userdata, a number (constant field), an expression string
 * or a Lua function f(x, y, z) (batch-called from C). Returns a NEW reference
 * that the caller must gr_field_free (or push). */
gr_field *gr_to_field(lua_State *L, int idx);
void gr_push_field(lua_State *L, gr_field *f);
gr_mesh *gr_check_mesh(lua_State *L, int idx);
void gr_push_mesh(lua_State *L, gr_mesh *m);
gr_rings *gr_check_rings(lua_State *L, int idx);
void gr_push_rings(lua_State *L, gr_rings *r);
gr_layer *gr_check_layer(lua_State *L, int idx);
void gr_push_layer(lua_State *L, gr_layer *l);

/* Per-primitive openers, each in its own bind_<name>.c. */
int gr_open_field(lua_State *L);    /* gradus.field.*, field methods */
int gr_open_mesh(lua_State *L);     /* gradus.mc, gradus.mesh.*, mesh methods */
int gr_open_distance(lua_State *L); /* gradus.distance.* */
int gr_open_slice(lua_State *L);    /* gradus.slice.*, rings methods */
int gr_open_hatch(lua_State *L);    /* gradus.hatch.*, layer methods, verify */
int gr_open_io(lua_State *L);       /* gradus.cli.*, gradus.svg.*, gradus.png.* */
int gr_open_clicat(lua_State *L);   /* gradus.cli.cat (after gr_open_io) */
int gr_open_yaml(lua_State *L);     /* gradus.yaml.* */
int gr_open_fs(lua_State *L);       /* gradus.fs.* (bind_fs.c) */
/* Where a C writer must write the output `path`: the job's output
 * transaction (lua/gradus/outputs.lua) stages it under a temporary name that
 * is renamed when every output is complete; outside a job, path itself.
 * The string is left on the Lua stack (it stays valid while there). */
const char *gr_lua_stage(lua_State *L, const char *path);
/* Raise if the sandbox (when on) refuses `path` for mode "r" (read) or "w"
 * (write or create); nothing otherwise. */
void gr_lua_guard(lua_State *L, const char *path, const char *mode);
int gr_open_place(lua_State *L);    /* gradus.place.*, gradus.kb.* */
int gr_open_view(lua_State *L);     /* gradus.view.* (bind_view.c) */
int gr_open_density(lua_State *L);  /* gradus.density.*, gradus.field.file */
struct gr_dtable *gr_test_dtable(lua_State *L, int idx); /* a density table or NULL */
/* bind_regions.c: job:regions{...}, and the stats' `regions` table (set into
 * the table on top of the stack; nothing without regions). */
int gr_l_job_regions(lua_State *L);
struct gr_job;
struct gr_job_stats;
void gr_regions_push_stats(lua_State *L, const struct gr_job *j, const struct gr_job_stats *st);

#endif
