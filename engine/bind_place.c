/* bind_place.c: Lua binding of placement (gradus.place.*) and of the
 * knowledge base (gradus.kb.*).
 *   local job = gradus.place.job{cell=2, cells={nx,ny,nz}, ...}
 *   local s = job:spec{surface="primitive", thickness="0.1", kind="sheet"}
 *   job:voxel(i, j, k, {spec=s, laser=1, seq=key})
 *   job:domain(field, {skin=0.2}) ; job:machine(machine_table)
 *   local stats, kept = job:run{output="x.cli", format="binary", kb=dir|true|false, ...}
 */
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include <unistd.h>
#include "bind.h"
#include "interrupt.h"
#include "cli.h"
#include "bind_ovf.h"
#include "kb.h"
#include "grid.h"
#include "place.h"
#include "regions.h"

#define JOB_MT "gradus.job"

typedef struct ljob { gr_job *j; } ljob;

static gr_job *check_job(lua_State *L, int idx) {
  ljob *b = luaL_checkudata(L, idx, JOB_MT);
  if (!b->j) luaL_argerror(L, idx, "job is closed");
  return b->j;
}

static int job_gc(lua_State *L) {
  ljob *b = luaL_checkudata(L, 1, JOB_MT);
  gr_job_free(b->j);
  b->j = NULL;
  return 0;
}

static int pattern_of(lua_State *L, const char *s) {
  if (!strcmp(s, "parallel")) return GR_PATTERN_PARALLEL;
  if (!strcmp(s, "zigzag")) return GR_PATTERN_ZIGZAG;
  if (!strcmp(s, "island")) return GR_PATTERN_ISLAND;
  return luaL_error(L, "bad option 'pattern' (parallel, zigzag or island, got '%s')", s);
}

/* A number option that must be finite and inside [lo, hi] (NaN and
 * infinities are refused by name; lua_pushfstring has no %g, hence the
 * buffer). */
static double opt_in(lua_State *L, int idx, const char *key, double def, double lo, double hi) {
  double v = gr_opt_number(L, idx, key, def);
  if (!(v >= lo && v <= hi)) {
    char msg[160];
    snprintf(msg, sizeof msg, "bad option '%s' (a finite number in [%g, %g] expected, got %g)", key, lo, hi, v);
    luaL_error(L, "%s", msg);
  }
  return v;
}

/* Option 'cell': a number (a cube) or {Lx, Ly, Lz}, each finite in
 * [1e-3, 1e3] mm. */
static void cell_opt(lua_State *L, int idx, double cell[3]) {
  int t = lua_getfield(L, idx, "cell");
  lua_pop(L, 1);
  if (t != LUA_TTABLE) {
    cell[0] = cell[1] = cell[2] = opt_in(L, idx, "cell", cell[0], 1e-3, 1e3);
    return;
  }
  gr_opt_vec(L, idx, "cell", 3, cell);
  for (int a = 0; a < 3; a++)
    if (!(cell[a] >= 1e-3 && cell[a] <= 1e3)) {
      char msg[160];
      snprintf(msg, sizeof msg, "bad option 'cell' (finite numbers in [0.001, 1000] mm expected, got %g)", cell[a]);
      luaL_error(L, "%s", msg);
    }
}

/* gradus.place.job{...} */
static int l_job(lua_State *L) {
  luaL_checktype(L, 1, LUA_TTABLE);
  ljob *b = lua_newuserdatauv(L, sizeof *b, 1);
  b->j = NULL;
  luaL_setmetatable(L, JOB_MT);
  gr_job_opts o = gr_job_defaults();
  cell_opt(L, 1, o.cell);
  double Lmax = fmax(o.cell[0], fmax(o.cell[1], o.cell[2]));
  gr_opt_vec(L, 1, "origin", 3, o.origin);
  double n[3] = {1, 1, 1};
  gr_opt_vec(L, 1, "cells", 3, n);
  for (int a = 0; a < 3; a++) {
    if (!(isfinite(o.origin[a]) && fabs(o.origin[a]) <= 1e6))
      return luaL_error(L, "bad option 'origin' (finite numbers in [-1e6, 1e6] mm expected, got %f)", o.origin[a]);
    if (!(n[a] >= 1 && n[a] <= 100000 && n[a] == (int)n[a]))
      return luaL_error(L, "bad option 'cells' (whole numbers in [1, 100000] expected, got %f)", n[a]);
    o.n[a] = (int)n[a];
  }
  o.layer = opt_in(L, 1, "layer", o.layer, 1e-4, 1e3);
  o.hatch = opt_in(L, 1, "hatch", o.hatch, 1e-4, 1e3);
  /* the in-plane grid has cell/slice_cell nodes a side, slice_cell <= hatch/2 */
  if (Lmax / o.hatch > 4096) {
    char msg[160];
    snprintf(msg, sizeof msg, "bad option 'hatch' (at least cell/4096 = %g mm for a cell of %g mm, got %g)",
             Lmax / 4096, Lmax, o.hatch);
    return luaL_error(L, "%s", msg);
  }
  o.beam_offset = opt_in(L, 1, "beam_offset", o.beam_offset, -1, gr_cell_min(o.cell));
  o.track = opt_in(L, 1, "track", o.track, -1, 1e3);
  o.contours = gr_opt_integer(L, 1, "contours", o.contours);
  o.contour_first = gr_opt_boolean(L, 1, "contour_first", o.contour_first);
  o.angle = opt_in(L, 1, "angle", o.angle, -1e4, 1e4);
  o.rotation = opt_in(L, 1, "rotation", o.rotation, -1e4, 1e4);
  o.pattern = pattern_of(L, gr_opt_string(L, 1, "pattern", "parallel"));
  o.alternate = gr_opt_boolean(L, 1, "alternate", 1);
  o.slice_cell = opt_in(L, 1, "slice_cell", o.slice_cell, -1, o.hatch);
  if (o.slice_cell > 0 && Lmax / o.slice_cell > 8192)
    return luaL_error(L, "bad option 'slice_cell' (at least cell/8192 expected)");
  o.res = gr_opt_integer(L, 1, "res", o.res);
  const char *mode = gr_opt_string(L, 1, "mode", "exact");
  if (strcmp(mode, "exact") && strcmp(mode, "mesh"))
    return luaL_error(L, "bad option 'mode' (exact or mesh, got '%s')", mode);
  o.exact = !strcmp(mode, "exact");
  o.quant = opt_in(L, 1, "quant", o.quant, 1e-9, 1);
  o.min_length = opt_in(L, 1, "min_length", o.min_length, 0, 1e3);
  o.threads = gr_opt_integer(L, 1, "threads", o.threads);
  if (o.threads < 1 || o.threads > 64)
    return luaL_error(L, "bad option 'threads' (1 to 64 expected, got %d)", o.threads);
  o.nlasers = gr_opt_integer(L, 1, "lasers", 1);
  o.share = gr_opt_boolean(L, 1, "share", o.share);
  o.faces = gr_opt_boolean(L, 1, "faces", o.faces);
  o.verify = gr_opt_boolean(L, 1, "verify", o.verify);
  o.max_pore = opt_in(L, 1, "max_pore", o.max_pore, 0, 1);
  o.max_overmelt = opt_in(L, 1, "max_overmelt", o.max_overmelt, 0, 1e3);
  o.max_dev = opt_in(L, 1, "max_dev", o.max_dev, 0, 1e3);
  gr_err e;
  gr_err_clear(&e);
  b->j = gr_job_new(&o, &e);
  if (!b->j) return gr_lua_error(L, &e);
  return 1;
}

/* spec options density_table= (thickness values are densities) and target= (a
 * field used instead of the thickness expression): both stay referenced from
 * the job's user value while the job lives. */
static void keep_density(lua_State *L, gr_spec *s) {
  lua_getfield(L, 2, "density_table");
  s->density = gr_test_dtable(L, -1);
  lua_getfield(L, 2, "target");
  s->target = lua_isnil(L, -1) ? NULL : gr_check_field(L, -1);
  if (lua_getiuservalue(L, 1, 1) != LUA_TTABLE) {
    lua_pop(L, 1);
    lua_newtable(L);
    lua_pushvalue(L, -1);
    lua_setiuservalue(L, 1, 1);
  }
  for (int k = -3; k <= -2; k++) {
    lua_pushvalue(L, k);
    lua_rawseti(L, -2, (lua_Integer)lua_rawlen(L, -2) + 1);
  }
  lua_pop(L, 3);
}

/* job:spec{surface=, level=, kind=, side=, thickness=, inside=, density_table=, target=} -> index (1-based) */
static int l_spec(lua_State *L) {
  gr_job *j = check_job(L, 1);
  luaL_checktype(L, 2, LUA_TTABLE);
  gr_spec s;
  memset(&s, 0, sizeof s);
  const char *name = gr_opt_string(L, 2, "surface", "primitive");
  s.surface = gr_tpms_lookup(name);
  if (s.surface < 0) return luaL_error(L, "bad option 'surface' (unknown surface '%s'; valid: %s)", name, gr_tpms_names());
  s.level = gr_opt_number(L, 2, "level", 0);
  const char *kind = gr_opt_string(L, 2, "kind", "sheet");
  if (strcmp(kind, "sheet") && strcmp(kind, "network"))
    return luaL_error(L, "bad option 'kind' (sheet or network, got '%s')", kind);
  s.network = !strcmp(kind, "network");
  s.side = gr_opt_integer(L, 2, "side", -1);
  lua_getfield(L, 2, "thickness");
  if (lua_type(L, -1) == LUA_TNUMBER) {
    double t = lua_tonumber(L, -1);
    snprintf(s.thickness, sizeof s.thickness, "%.17g", t);
  } else if (lua_type(L, -1) == LUA_TSTRING) {
    size_t len;
    const char *t = lua_tolstring(L, -1, &len);
    if (len >= sizeof s.thickness) return luaL_error(L, "bad option 'thickness' (expression longer than %d)", (int)sizeof s.thickness - 1);
    memcpy(s.thickness, t, len + 1);
  } else {
    return luaL_error(L, "bad option 'thickness' (a number or an expression in x,y,z,u,v,w,L expected, got %s)",
                      luaL_typename(L, -1));
  }
  lua_pop(L, 1);
  const char *in = gr_opt_string(L, 2, "inside", "");
  if (strlen(in) >= sizeof s.inside) return luaL_error(L, "bad option 'inside' (expression too long)");
  strcpy(s.inside, in);
  if (s.network && in[0])
    return luaL_error(L, "bad option 'inside' (the inside half-thickness of an asymmetric sheet: a network has one side, "
                         "grown by thickness)");
  keep_density(L, &s);
  gr_err e;
  gr_err_clear(&e);
  int idx = gr_job_add_spec(j, &s, &e);
  if (idx < 0) return luaL_error(L, "bad option 'thickness' (%s)", e.msg);
  lua_pushinteger(L, idx + 1);
  return 1;
}

/* job:voxel(i, j, k, {spec=, laser=, seq=}) with 0-based i,j,k; laser 1-based */
static int l_voxel(lua_State *L) {
  gr_job *j = check_job(L, 1);
  int i = (int)luaL_checkinteger(L, 2), jj = (int)luaL_checkinteger(L, 3), k = (int)luaL_checkinteger(L, 4);
  int spec = gr_opt_integer(L, 5, "spec", 1) - 1;
  int laser = gr_opt_integer(L, 5, "laser", 0) - 1;
  const gr_job_opts *o = gr_job_options(j);
  double seq = gr_opt_number(L, 5, "seq", i + o->n[0] * (double)jj);
  gr_err e;
  gr_err_clear(&e);
  if (gr_job_set_voxel(j, i, jj, k, spec, laser, seq, &e)) return gr_lua_error(L, &e);
  return 0;
}

static int l_domain(lua_State *L) {
  gr_job *j = check_job(L, 1);
  gr_field *f = gr_to_field(L, 2);
  double skin = opt_in(L, 3, "skin", 0, 0, 1e3);
  gr_err e;
  gr_err_clear(&e);
  int rc = gr_job_set_domain(j, f, skin, &e);
  gr_field_free(f);
  if (rc) return gr_lua_error(L, &e);
  return 0;
}

/* job:machine(m) with m as normalised by gradus.lasers */
static int l_machine(lua_State *L) {
  gr_job *j = check_job(L, 1);
  luaL_checktype(L, 2, LUA_TTABLE);
  lua_getfield(L, 2, "lasers");
  int n = (int)luaL_len(L, -1);
  gr_machine m = gr_machine_default(n);
  static const char *const kinds[GR_NKINDS] = {"contour", "hatch", "edge"};
  for (int l = 0; l < n && l < GR_MAX_LASERS; l++) {
    lua_geti(L, -1, l + 1);
    int t = lua_gettop(L);
    for (int k = 0; k < GR_NKINDS; k++) {
      lua_getfield(L, t, kinds[k]);
      m.speed[l][k] = gr_opt_number(L, -1, "speed", m.speed[l][k]);
      lua_pop(L, 1);
    }
    lua_getfield(L, t, "field");
    if (lua_istable(L, -1)) {
      gr_opt_vec(L, -1, "lo", 2, m.lo[l]);
      gr_opt_vec(L, -1, "hi", 2, m.hi[l]);
    }
    lua_pop(L, 2);
  }
  lua_pop(L, 1);
  m.jump_speed = gr_opt_number(L, 2, "jump_speed", m.jump_speed);
  m.jump_delay = gr_opt_number(L, 2, "jump_delay", 0);
  m.polygon_delay = gr_opt_number(L, 2, "polygon_delay", 0);
  m.recoat_time = gr_opt_number(L, 2, "recoat_time", 0);
  m.stitch = gr_opt_number(L, 2, "stitch", GR_STITCH_DEFAULT);
  gr_err e;
  gr_err_clear(&e);
  if (gr_job_set_machine(j, &m, &e)) return gr_lua_error(L, &e);
  return 0;
}

static int l_layers(lua_State *L) {
  lua_pushinteger(L, gr_job_layers(check_job(L, 1)));
  return 1;
}

/* ---- run ---- */
typedef struct sinkctx {
  gr_cli_writer *w[GR_MAX_LASERS + 1]; /* [0] all, or one per laser when split */
  gr_ovf_writer *ovf;  /* format "ovf": instead of w[] */
  int split, nlasers;
  gr_layer *tmp;
  int *keep;           /* layer numbers to keep */
  int nkeep;
  gr_layer **kept;
  double t_write;      /* seconds spent writing */
  int g0, g1;          /* first and last layer written */
} sinkctx;

static int sink(void *ud, int g, const gr_layer *l, gr_err *e) {
  sinkctx *s = ud;
  double t0 = gr_now();
  int rc = GR_OK;
  if (gr_interrupted()) { /* Ctrl-C: stop here, the writers remove their temporaries */
    gr_interrupt_reported();
    return gr_fail(e, GR_EIO, "interrupted (Ctrl-C) before layer %d (z = %.4f mm) of layers %d..%d: %d written, nothing kept",
                   g, l->z, s->g0, s->g1, g - s->g0);
  }
  if (s->split) {
    for (int la = 0; la < s->nlasers && rc == GR_OK; la++) {
      gr_layer_clear(s->tmp, l->z);
      for (size_t b = 0; b < l->nb; b++)
        if (l->b[b].laser == la &&
            gr_layer_add(s->tmp, l->b[b].shape, l->b[b].kind, la, l->b[b].dir, l->xy + 2 * l->b[b].start, l->b[b].n))
          return gr_fail(e, GR_EMEM, "out of memory");
        else if (l->b[b].laser == la) s->tmp->b[s->tmp->nb - 1].region = l->b[b].region;
      rc = gr_cli_write_layer(s->w[la + 1], s->tmp, e);
    }
  }
  if (rc == GR_OK && s->w[0]) rc = gr_cli_write_layer(s->w[0], l, e);
  if (rc == GR_OK && s->ovf) rc = gr_ovf_write_layer(s->ovf, l, NULL, e);
  s->t_write += gr_now() - t0;
  for (int i = 0; i < s->nkeep && rc == GR_OK; i++)
    if (s->keep[i] == g && !s->kept[i]) {
      s->kept[i] = gr_layer_new(l->z);
      if (!s->kept[i] || gr_layer_append(s->kept[i], l, 0, 0)) return gr_fail(e, GR_EMEM, "out of memory");
    }
  return rc;
}

typedef struct progctx { int quiet; double t0, last; } progctx;

static void progress(void *ud, const char *stage, long done, long total) {
  progctx *p = ud;
  if (p->quiet) return;
  double now = gr_now();
  if (done < total && now - p->last < 0.25) return;
  p->last = now;
  double el = now - p->t0, rate = el > 0 ? done / el : 0;
  /* the template stage counts template layers (every template has many) */
  const char *label = strcmp(stage, "templates") == 0 ? "template layers" : stage;
  fprintf(stderr, "\r%s: %ld/%ld (%.1f/s, %.0f s left)   %s", label, done, total, rate,
          rate > 0 ? (total - done) / rate : 0.0, done >= total ? "\n" : "");
  if (done >= total) p->t0 = now;
  fflush(stderr);
}


/* The recipe's qualification rule: opts.qualify(quality) -> ok [, reason],
 * quality = {pore=, overmelt=, max_dev= (mm), layers=, thin_walls=, key=}.
 * A Lua error in the rule refuses the template with the error as reason. */
typedef struct qualctx { lua_State *L; int ref; } qualctx;
static int qualify_cb(void *ud, const char *key, const double q[4], long thin, char *why, size_t n) {
  qualctx *c = ud;
  lua_State *L = c->L;
  lua_rawgeti(L, LUA_REGISTRYINDEX, c->ref);
  lua_createtable(L, 0, 6);
  static const char *const names[4] = {"pore", "overmelt", "max_dev", "layers"};
  for (int i = 0; i < 4; i++)
    if (!isnan(q[i])) gr_lua_setnum(L, names[i], q[i]);
  lua_pushinteger(L, thin);
  lua_setfield(L, -2, "thin_walls");
  lua_pushstring(L, key);
  lua_setfield(L, -2, "key");
  if (lua_pcall(L, 1, 2, 0) != LUA_OK) {
    snprintf(why, n, "qualify rule failed: %s", lua_tostring(L, -1));
    lua_pop(L, 1);
    return 0;
  }
  int ok = lua_toboolean(L, -2);
  if (!ok && lua_isstring(L, -1)) snprintf(why, n, "%s", lua_tostring(L, -1));
  lua_pop(L, 2);
  return ok;
}
static void push_stats(lua_State *L, gr_job *j, const sinkctx *s, double units) {
  const gr_job_stats *st = gr_job_get_stats(j);
  lua_newtable(L);
  gr_lua_setint(L, "layers", st->layers);
  gr_lua_setint(L, "layers_total", gr_job_layers(j));
  gr_lua_setint(L, "voxels", st->voxels);
  gr_lua_setint(L, "trimmed_voxels", st->trimmed);
  gr_lua_setint(L, "trimmed_templates", st->trimmed_classes);
  lua_newtable(L);
  gr_lua_setint(L, "unique", st->classes);
  gr_lua_setint(L, "built", st->built);
  gr_lua_setint(L, "reused", st->reused);
  gr_lua_setint(L, "corrupt_rebuilt", st->kb_corrupt);
  gr_lua_setint(L, "stored", st->kb_stored);
  gr_lua_setint(L, "not_stored", st->kb_not_stored);
  gr_lua_setint(L, "held_max", st->held_max);
  gr_lua_setint(L, "banded_rows", st->banded_rows);
  /* share of the unique templates taken from the knowledge base (0 when none
   * was reused), and voxels per template (how much the job repeats itself) */
  gr_lua_setnum(L, "reuse_ratio", st->classes ? (double)st->reused / st->classes : 0);
  gr_lua_setnum(L, "voxels_per_template", st->classes ? (double)st->voxels / st->classes : 0);
  gr_lua_setint(L, "verified", st->verified);
  gr_lua_setint(L, "unqualified", st->unqualified);
  if (st->unqualified_why[0]) {
    lua_pushstring(L, st->unqualified_why);
    lua_setfield(L, -2, "unqualified_reason");
  }
  lua_setfield(L, -2, "templates");
  lua_newtable(L);
  static const char *const kinds[GR_NKINDS] = {"contour", "hatch", "edge"};
  for (int k = 0; k < GR_NKINDS; k++) {
    lua_newtable(L);
    gr_lua_setint(L, "count", (long long)st->vectors[k]);
    gr_lua_setnum(L, "length", st->length[k]);
    lua_setfield(L, -2, kinds[k]);
  }
  lua_setfield(L, -2, "vectors");
  lua_newtable(L);
  gr_lua_setint(L, "count", (long long)st->jumps);
  gr_lua_setnum(L, "length", st->jump_length);
  lua_setfield(L, -2, "jumps");
  lua_newtable(L);
  const gr_job_opts *o = gr_job_options(j);
  double total = 0;
  for (int la = 0; la < o->nlasers; la++) total += st->laser_time[la];
  for (int la = 0; la < o->nlasers; la++) {
    lua_newtable(L);
    gr_lua_setnum(L, "length", st->laser_length[la]);
    gr_lua_setnum(L, "scan_time_s", st->laser_time[la]);
    gr_lua_setnum(L, "share", total > 0 ? st->laser_time[la] / total : 0);
    lua_rawseti(L, -2, la + 1);
  }
  lua_setfield(L, -2, "lasers");
  gr_lua_setnum(L, "build_time_s", st->build_time);
  gr_lua_setnum(L, "balanced_time_s", st->balanced_time);
  /* balance of the lasers' work (recoating, equal for all, left out) */
  double busy = st->build_time - st->recoat_time;
  gr_lua_setnum(L, "balance_efficiency", busy > 0 ? (st->balanced_time - st->recoat_time) / busy : 1);
  gr_lua_setint(L, "thin_walls", st->thin_walls);
  gr_regions_push_stats(L, j, st);
  if (st->layers > 0)
    gr_lua_setnum(L, "relative_density", st->solid_area / (st->layers * o->n[0] * (double)o->n[1] * o->cell[0] * o->cell[1]));
  gr_lua_setnum(L, "solid_volume_mm3", st->solid_area * o->layer);
  gr_lua_setint(L, "dropped_short_vectors", st->dropped);
  gr_lua_setint(L, "split_loops", st->split_loops);
  gr_lua_setnum(L, "recoat_time_s", st->recoat_time);
  double lt = 0; /* all lasers' time: marking plus jumps and delays */
  for (int la = 0; la < GR_MAX_LASERS; la++) lt += st->laser_time[la];
  gr_lua_setnum(L, "scan_time_s", lt - st->jump_time);
  gr_lua_setnum(L, "jump_time_s", st->jump_time);
  lua_newtable(L);
  gr_lua_setint(L, "dropped_short", st->short_loops);
  gr_lua_setnum(L, "dropped_short_length", st->short_length);
  lua_setfield(L, -2, "contours");
  lua_newtable(L);
  gr_lua_setnum(L, "classify", st->seconds[0]);
  gr_lua_setnum(L, "templates", st->seconds[1]);
  gr_lua_setnum(L, "layers", st->seconds[2]);
  gr_lua_setnum(L, "write", s->t_write);
  gr_lua_setnum(L, "total", st->seconds[3]);
  lua_setfield(L, -2, "seconds");
  gr_lua_setnum(L, "units", units);
  /* the values the job used where the caller left a default ("auto") */
  lua_newtable(L);
  gr_lua_setnum(L, "beam_offset", o->beam_offset);
  gr_lua_setnum(L, "slice_cell", o->slice_cell);
  gr_lua_setnum(L, "track", o->track);
  gr_lua_setint(L, "threads", o->threads);
  lua_setfield(L, -2, "effective");
  /* peak resident memory from /proc */
  FILE *f = fopen("/proc/self/status", "r");
  if (f) {
    char line[256];
    while (fgets(line, sizeof line, f))
      if (!strncmp(line, "VmHWM:", 6)) gr_lua_setnum(L, "peak_rss_mb", atof(line + 6) / 1024.0);
    fclose(f);
  }
  const char *w = gr_job_warning(j);
  if (w && *w) { lua_pushstring(L, w); lua_setfield(L, -2, "warning"); }
}

/* Remove the temporaries that stopped jobs left in the knowledge base, and
 * say so on stderr (a failure to look is not the job's failure). */
static void sweep_kb(gr_kb *kb) {
  gr_kb_report rep;
  gr_err e;
  gr_err_clear(&e);
  if (gr_kb_sweep(kb, &rep, &e) == GR_OK && rep.removed)
    fprintf(stderr, "gradus: knowledge base %s: removed %zu temporary file(s) left by stopped jobs:\n%s", gr_kb_dir(kb),
            rep.removed, rep.messages ? rep.messages : "");
  gr_kb_report_clear(&rep);
}

/* job:run{output=, format="ascii"|"binary", kb=dir|true|false, direct=,
 *         first=, last=, keep={g...}, split=, quiet=} -> stats, kept layers */
/* The writers of a job's output (staged paths outs[]): one OVF file (the
 * lasers inside it), or a CLI file and, with split, one per laser. */
static int open_outputs(lua_State *L, sinkctx *s, const gr_job_opts *o, int ovf, const char *const *outs,
                        const gr_cli_header *h, gr_err *e) {
  if (ovf) {
    s->ovf = gr_lua_ovf_open(L, 2, outs[0], o, h->layers, e);
    return s->ovf ? GR_OK : e->code ? e->code : GR_EIO;
  }
  for (int la = -1; la < (s->split ? o->nlasers : 0); la++)
    if (!(s->w[la + 1] = gr_cli_open(outs[la + 1], h, e))) return e->code ? e->code : GR_EIO;
  return GR_OK;
}

/* What the output holds (ascii, long, short, short+long, ovf; NULL: no
 * output) and the zero-length marks the short form's rounding left out. */
typedef struct outform { const char *form; long rpts, rvec; } outform;

/* Commit every writer if the job went well (rc == GR_OK), else remove the
 * temporaries; what was written into *of. Returns rc, or the first close's
 * error (into *e). */
static int close_outputs(sinkctx *s, gr_job *j, int rc, gr_err *e, outform *of) {
  of->form = s->ovf ? "ovf" : s->w[0] ? gr_cli_form(s->w[0]) : NULL;
  of->rpts = of->rvec = 0;
  if (s->w[0]) gr_cli_rounded(s->w[0], &of->rpts, &of->rvec);
  for (int w = 0; w <= GR_MAX_LASERS; w++) {
    if (!s->w[w]) continue;
    gr_err e2;
    gr_err_clear(&e2);
    int crc = gr_cli_close(s->w[w], rc == GR_OK, &e2);
    if (rc == GR_OK && crc) { rc = crc; *e = e2; }
  }
  if (s->ovf) {
    gr_err e2;
    gr_err_clear(&e2);
    gr_ovf_set_volume(s->ovf, gr_job_get_stats(j)->solid_area * gr_job_options(j)->layer);
    int crc = gr_ovf_close(s->ovf, rc == GR_OK, &e2);
    if (rc == GR_OK && crc) { rc = crc; *e = e2; }
  }
  return rc;
}

/* stats.form and, where the short form left marks out, stats.rounded_out
 * (said, since the file then holds fewer points than the stats count). */
static void push_form(lua_State *L, const outform *of) {
  if (of->form) {
    lua_pushstring(L, of->form);
    lua_setfield(L, -2, "form");
  }
  if (of->rpts || of->rvec) {
    lua_createtable(L, 0, 2);
    lua_pushinteger(L, of->rpts);
    lua_setfield(L, -2, "points");
    lua_pushinteger(L, of->rvec);
    lua_setfield(L, -2, "vectors");
    lua_setfield(L, -2, "rounded_out");
  }
}

static int l_run(lua_State *L) {
  gr_job *j = check_job(L, 1);
  luaL_checktype(L, 2, LUA_TTABLE);
  const char *out = gr_opt_string(L, 2, "output", NULL);
  const char *format = gr_opt_string(L, 2, "format", "ascii");
  if (strcmp(format, "ascii") && strcmp(format, "binary") && strcmp(format, "binary-long") && strcmp(format, "ovf"))
    return luaL_error(L, "bad option 'format' (ascii, binary, binary-long or ovf, got '%s')", format);
  int binary = !strncmp(format, "binary", 6);
  gr_job_run_opts r;
  memset(&r, 0, sizeof r);
  r.direct = gr_opt_boolean(L, 2, "direct", 0);
  static const char *const stores[] = {"reused", "all", "none"};
  const char *store = gr_opt_string(L, 2, "kb_store", "reused");
  for (r.kb_store = 0; r.kb_store < 3 && strcmp(store, stores[r.kb_store]); r.kb_store++) {}
  if (r.kb_store == 3) return luaL_error(L, "bad option 'kb_store' (all, reused or none, got '%s')", store);
  r.first = gr_opt_integer(L, 2, "first", 0);
  r.last = gr_opt_integer(L, 2, "last", 0);
  int split = gr_opt_boolean(L, 2, "split", 0);
  /* the output paths as the job's output transaction stages them (this may
   * raise, so before anything is allocated) */
  const char *outs[GR_MAX_LASERS + 1] = {NULL};
  int nsplit = out && split ? gr_job_options(j)->nlasers : 0;
  if (out) outs[0] = gr_lua_stage(L, out);
  for (int la = 0; nsplit > 1 && la < nsplit; la++) {
    char path[4200];
    size_t n = strlen(out);
    if (n > 4 && !strcmp(out + n - 4, ".cli")) snprintf(path, sizeof path, "%.*s_laser%d.cli", (int)(n - 4), out, la + 1);
    else snprintf(path, sizeof path, "%s_laser%d.cli", out, la + 1);
    outs[la + 1] = gr_lua_stage(L, path);
  }
  progctx pc = {gr_opt_boolean(L, 2, "quiet", 1), gr_now(), 0};
  r.progress = progress;
  r.progress_ud = &pc;
  qualctx qc = {L, LUA_NOREF};
  lua_getfield(L, 2, "qualify");
  if (lua_isfunction(L, -1)) {
    qc.ref = luaL_ref(L, LUA_REGISTRYINDEX);
    r.qualify = qualify_cb;
    r.qualify_ud = &qc;
  } else {
    if (!lua_isnil(L, -1)) return luaL_error(L, "job:run: option 'qualify' must be a function");
    lua_pop(L, 1);
  }
  /* knowledge base: a directory, true (the default directory) or false */
  char kbdir[4096] = "";
  lua_getfield(L, 2, "kb");
  if (lua_type(L, -1) == LUA_TSTRING) snprintf(kbdir, sizeof kbdir, "%s", lua_tostring(L, -1));
  else if (lua_toboolean(L, -1)) gr_kb_default_dir(kbdir, sizeof kbdir);
  lua_pop(L, 1);
  if (kbdir[0]) gr_lua_guard(L, kbdir, "w"); /* the sandbox's say, before anything is allocated */
  gr_err e;
  gr_err_clear(&e);
  sinkctx s;
  memset(&s, 0, sizeof s);
  const gr_job_opts *o = gr_job_options(j);
  s.nlasers = o->nlasers;
  s.split = split && o->nlasers > 1;
  /* layers to keep for pictures */
  lua_getfield(L, 2, "keep");
  int nkeep = lua_istable(L, -1) ? (int)luaL_len(L, -1) : 0;
  lua_pop(L, 1);
  s.keep = calloc(nkeep + 1, sizeof *s.keep);
  s.kept = calloc(nkeep + 1, sizeof *s.kept);
  s.tmp = gr_layer_new(0);
  if (!s.keep || !s.kept || !s.tmp) { free(s.keep); free(s.kept); gr_layer_free(s.tmp); return luaL_error(L, "out of memory"); }
  lua_getfield(L, 2, "keep");
  for (int i = 0; i < nkeep; i++) {
    lua_geti(L, -1, i + 1);
    s.keep[i] = (int)lua_tointeger(L, -1);
    lua_pop(L, 1);
  }
  lua_pop(L, 1);
  s.nkeep = nkeep;
  /* writers */
  gr_cli_header h = gr_cli_header_defaults();
  h.binary = binary;
  h.nlasers = o->nlasers;
  h.regions = gr_regions_mask(j);
  int ga = r.first > 0 ? r.first : 1, gb = r.last > 0 && r.last < gr_job_layers(j) ? r.last : gr_job_layers(j);
  h.layers = gb - ga + 1;
  s.g0 = ga;
  s.g1 = gb;
  for (int a = 0; a < 3; a++) {
    h.lo[a] = o->origin[a];
    h.hi[a] = o->origin[a] + o->n[a] * o->cell[a];
  }
  /* the part's true extent: extent = {x, y, z} max corner (mm), and the
   * heights of the layers written */
  if (lua_getfield(L, 2, "extent") == LUA_TTABLE) gr_opt_vec(L, 2, "extent", 3, h.hi);
  lua_pop(L, 1);
  h.lo[2] = o->origin[2] + (ga - 1) * o->layer;
  if (o->origin[2] + gb * o->layer < h.hi[2]) h.hi[2] = o->origin[2] + gb * o->layer;
  /* binary: the short form (16-bit coordinates) when the part's box fits at the unit */
  h.short_form = !strcmp(format, "binary");
  for (int a = 0; a < 3; a++) h.short_form &= h.lo[a] >= 0 && h.hi[a] / h.units <= 65535;
  int rc = GR_OK;
  gr_kb *kb = NULL;
  if (kbdir[0] && !r.direct) {
    kb = gr_kb_open(kbdir, &e);
    if (!kb) rc = e.code ? e.code : GR_EIO;
    else sweep_kb(kb);
  }
  if (rc == GR_OK && out) rc = open_outputs(L, &s, o, !strcmp(format, "ovf"), outs, &h, &e);
  if (rc == GR_OK) {
    r.kb = kb;
    r.sink = sink;
    r.sink_ud = &s;
    rc = gr_job_run(j, &r, &e);
  }
  outform of;
  rc = close_outputs(&s, j, rc, &e, &of);
  gr_kb_close(kb);
  if (gr_job_get_stats(j)->kb_corrupt) /* also in the stats; said here so that nobody misses it */
    fprintf(stderr, "gradus: knowledge base %s: %d damaged record(s) rebuilt (%s)\n", kbdir,
            gr_job_get_stats(j)->kb_corrupt, gr_job_warning(j));
  gr_layer_free(s.tmp);
  luaL_unref(L, LUA_REGISTRYINDEX, qc.ref);
  if (rc) {
    for (int i = 0; i < nkeep; i++) gr_layer_free(s.kept[i]);
    free(s.kept);
    free(s.keep);
    return gr_lua_error(L, &e);
  }
  push_stats(L, j, &s, h.units);
  push_form(L, &of);
  lua_newtable(L);
  for (int i = 0; i < nkeep; i++) {
    if (!s.kept[i]) continue;
    gr_push_layer(L, s.kept[i]);
    lua_rawseti(L, -2, s.keep[i]);
  }
  free(s.kept);
  free(s.keep);
  return 2;
}

static int job_tostring(lua_State *L) {
  gr_job *j = check_job(L, 1);
  const gr_job_opts *o = gr_job_options(j);
  if (gr_cell_cube(o->cell))
    lua_pushfstring(L, "job: %d x %d x %d voxels of %f mm, %d layers of %f mm", o->n[0], o->n[1], o->n[2], o->cell[0],
                    gr_job_layers(j), o->layer);
  else
    lua_pushfstring(L, "job: %d x %d x %d voxels of %f x %f x %f mm, %d layers of %f mm", o->n[0], o->n[1], o->n[2],
                    o->cell[0], o->cell[1], o->cell[2], gr_job_layers(j), o->layer);
  return 1;
}

/* ---- knowledge base ---- */
static const char *kb_dir_arg(lua_State *L, int idx, char *buf, size_t n) {
  if (lua_isnoneornil(L, idx)) {
    gr_kb_default_dir(buf, n);
    return buf;
  }
  gr_lua_guard(L, luaL_checkstring(L, idx), "w");
  return luaL_checkstring(L, idx);
}

static int l_kb_default_dir(lua_State *L) {
  char buf[4096];
  gr_kb_default_dir(buf, sizeof buf);
  lua_pushstring(L, buf);
  return 1;
}

static const luaL_Reg job_methods[] = {
    {"spec", l_spec},     {"voxel", l_voxel}, {"domain", l_domain}, {"machine", l_machine},
    {"layers", l_layers}, {"run", l_run},     {"regions", gr_l_job_regions}, {NULL, NULL}};

static void push_entry(lua_State *L, const char *key, const char *sig, size_t bytes, int qualified,
                       const double *quality, long long created) {
  lua_newtable(L);
  lua_pushstring(L, key);
  lua_setfield(L, -2, "key");
  lua_pushstring(L, sig ? sig : "");
  lua_setfield(L, -2, "signature");
  lua_pushboolean(L, gr_kb_stale(sig));
  lua_setfield(L, -2, "stale");
  gr_lua_setint(L, "bytes", (long long)bytes);
  lua_pushboolean(L, qualified);
  lua_setfield(L, -2, "qualified");
  gr_lua_setint(L, "created", created);
  lua_newtable(L);
  static const char *const qn[4] = {"pore_max", "overmelt_max", "contour_dev_max", "layers_verified"};
  for (int i = 0; i < 4; i++)
    if (!isnan(quality[i])) gr_lua_setnum(L, qn[i], quality[i]);
  lua_setfield(L, -2, "quality");
}

/* gradus.kb.list([dir]) -> array of {key, signature, bytes, qualified, created, quality} */
static int l_kb_list(lua_State *L) {
  char buf[4096];
  const char *dir = kb_dir_arg(L, 1, buf, sizeof buf);
  gr_err e;
  gr_err_clear(&e);
  gr_kb *kb = gr_kb_open(dir, &e);
  if (!kb) return gr_lua_error(L, &e);
  gr_kb_entry *v = NULL;
  size_t n = 0;
  char warn[512] = "";
  int rc = gr_kb_list(kb, &v, &n, warn, sizeof warn, &e);
  gr_kb_close(kb);
  if (rc) return gr_lua_error(L, &e);
  lua_createtable(L, (int)n, 0);
  for (size_t i = 0; i < n; i++) {
    push_entry(L, v[i].key, v[i].signature, v[i].bytes, v[i].qualified, v[i].quality, v[i].created);
    lua_rawseti(L, -2, (lua_Integer)i + 1);
  }
  gr_kb_entries_free(v, n);
  if (warn[0]) { lua_pushstring(L, warn); return 2; }
  return 1;
}

/* gradus.kb.show(dir, key) -> table with the template's summary, or nil */
static int l_kb_show(lua_State *L) {
  char buf[4096];
  const char *dir = kb_dir_arg(L, 1, buf, sizeof buf);
  const char *key = luaL_checkstring(L, 2);
  gr_err e;
  gr_err_clear(&e);
  gr_kb *kb = gr_kb_open(dir, &e);
  if (!kb) return gr_lua_error(L, &e);
  /* a key prefix is enough when unique */
  gr_kb_entry *v = NULL;
  size_t n = 0;
  char full[65] = "";
  if (gr_kb_list(kb, &v, &n, NULL, 0, &e) == GR_OK) {
    int found = 0;
    for (size_t i = 0; i < n; i++)
      if (!strncmp(v[i].key, key, strlen(key))) { memcpy(full, v[i].key, 65); found++; }
    if (found != 1) full[0] = 0;
    gr_kb_entries_free(v, n);
  }
  gr_template *t = NULL;
  char warn[512] = "";
  int rc = full[0] ? gr_kb_get(kb, full, &t, warn, sizeof warn, &e) : GR_OK;
  gr_kb_close(kb);
  if (rc) return gr_lua_error(L, &e);
  if (!t) { lua_pushnil(L); lua_pushstring(L, warn[0] ? warn : "no such template"); return 2; }
  push_entry(L, t->key, t->signature, 0, t->qualified, t->quality, t->created);
  gr_lua_setint(L, "layers", t->nlayers);
  size_t pts = 0, rings = 0, paths = 0;
  for (int q = 0; q < t->nlayers; q++) {
    for (int s = 0; s < t->nslots; s++) { rings += t->rings[q * t->nslots + s]->nrings; pts += t->rings[q * t->nslots + s]->npts; }
    if (t->extra && t->extra[q]) paths += t->extra[q]->nb;
  }
  gr_lua_setint(L, "rings", (long long)rings);
  gr_lua_setint(L, "points", (long long)pts);
  gr_lua_setint(L, "contour_pieces", (long long)paths);
  if (t->meta) { lua_pushstring(L, t->meta); lua_setfield(L, -2, "meta"); }
  gr_template_free(t);
  return 1;
}

static void push_report(lua_State *L, const gr_kb_report *r) {
  lua_newtable(L);
  gr_lua_setint(L, "ok", (long long)r->ok);
  gr_lua_setint(L, "corrupt", (long long)r->corrupt);
  gr_lua_setint(L, "orphans", (long long)r->orphans);
  gr_lua_setint(L, "removed", (long long)r->removed);
  gr_lua_setint(L, "index_entries", (long long)r->index_entries);
  lua_pushboolean(L, r->index_ok);
  lua_setfield(L, -2, "index_ok");
  if (r->messages) { lua_pushstring(L, r->messages); lua_setfield(L, -2, "messages"); }
}

/* Open the knowledge base named by argument 1 (or the default), run verify
 * (opts NULL) or prune, push the report. */
static int kb_report(lua_State *L, const gr_kb_prune_opts *prune) {
  char buf[4096];
  const char *dir = kb_dir_arg(L, 1, buf, sizeof buf);
  gr_err e;
  gr_err_clear(&e);
  gr_kb *kb = gr_kb_open(dir, &e);
  if (!kb) return gr_lua_error(L, &e);
  gr_kb_report r;
  memset(&r, 0, sizeof r);
  int rc = prune ? gr_kb_prune(kb, prune, &r, &e) : gr_kb_verify(kb, &r, &e);
  gr_kb_close(kb);
  if (rc) { gr_kb_report_clear(&r); return gr_lua_error(L, &e); }
  push_report(L, &r);
  gr_kb_report_clear(&r);
  return 1;
}

/* gradus.kb.verify([dir]) */
static int l_kb_verify(lua_State *L) { return kb_report(L, NULL); }

/* gradus.kb.prune([dir [, {older_than = unix seconds}]]) */
static int l_kb_prune(lua_State *L) {
  gr_kb_prune_opts po;
  memset(&po, 0, sizeof po);
  po.older_than = (long long)gr_opt_number(L, 2, "older_than", 0);
  return kb_report(L, &po);
}

/* gradus.place.check_size({nx, ny, nz}, cell or {Lx, Ly, Lz}): raises when
 * the cells are more voxels than a job holds (gr_job_check_size), before a
 * recipe spends time on a box that large. */
static int l_check_size(lua_State *L) {
  luaL_checktype(L, 1, LUA_TTABLE);
  int n[3];
  double cell[3];
  for (int a = 0; a < 3; a++) {
    lua_rawgeti(L, 1, a + 1);
    n[a] = (int)luaL_checkinteger(L, -1);
    lua_pop(L, 1);
    if (lua_type(L, 2) == LUA_TTABLE) {
      lua_rawgeti(L, 2, a + 1);
      cell[a] = luaL_checknumber(L, -1);
      lua_pop(L, 1);
    } else {
      cell[a] = luaL_checknumber(L, 2);
    }
  }
  gr_err e;
  gr_err_clear(&e);
  if (gr_job_check_size(n, cell, &e)) return gr_lua_error(L, &e);
  return 0;
}

static const luaL_Reg place_fns[] = {{"job", l_job}, {"check_size", l_check_size}, {NULL, NULL}};
static const luaL_Reg kb_fns[] = {{"list", l_kb_list},       {"show", l_kb_show},
                                  {"verify", l_kb_verify},   {"prune", l_kb_prune},
                                  {"default_dir", l_kb_default_dir}, {NULL, NULL}};

int gr_open_place(lua_State *L) {
  luaL_newmetatable(L, JOB_MT);
  lua_pushcfunction(L, job_gc);
  lua_setfield(L, -2, "__gc");
  lua_pushcfunction(L, job_gc);
  lua_setfield(L, -2, "__close");
  lua_pushcfunction(L, job_tostring);
  lua_setfield(L, -2, "__tostring");
  luaL_newlib(L, job_methods);
  lua_setfield(L, -2, "__index");
  lua_pop(L, 1);
  luaL_newlib(L, place_fns);
  lua_setfield(L, -2, "place");
  luaL_newlib(L, kb_fns);
  lua_setfield(L, -2, "kb");
  return 0;
}
