/* bind_hatch.c: Lua binding of the hatch primitive and of layers:
 * gradus.hatch.layer/region/angle/verify, gradus.layer.new and the layer
 * methods (stats, blocks, z, bounds, translate, append, add, __tostring).
 * See doc/api/hatch.md. */
#include <math.h>
#include <stdio.h>
#include <string.h>
#include "bind.h"
#include "hatch.h"
#include "verify.h"

static const char *const KIND_NAMES[] = {"contour", "hatch", "edge", NULL};
static const char *const SHAPE_NAMES[] = {"closed", "open", "segments", NULL};
static const char *const PATTERN_NAMES[] = {"parallel", "zigzag", "island", NULL};

/* Raise on option keys not in `allowed` (catches typos such as "spaceing"). */
static void check_keys(lua_State *L, int idx, const char *fn, const char *const *allowed) {
  if (lua_isnoneornil(L, idx)) return;
  luaL_checktype(L, idx, LUA_TTABLE);
  lua_pushnil(L);
  while (lua_next(L, idx)) {
    lua_pop(L, 1);
    int ok = 0;
    if (lua_type(L, -1) == LUA_TSTRING) {
      const char *k = lua_tostring(L, -1);
      for (const char *const *a = allowed; *a && !ok; a++) ok = strcmp(*a, k) == 0;
    }
    if (!ok) {
      const char *k = lua_type(L, -1) == LUA_TSTRING ? lua_tostring(L, -1) : luaL_typename(L, -1);
      luaL_error(L, "%s: unknown option '%s'", fn, k);
    }
  }
}

/* A rings userdata, or a table of rings {{x1, y1, x2, y2, ...}, ...}
 * (converted to a new rings object that the caller frees: *owned = 1). */
static gr_rings *to_rings(lua_State *L, int idx, int *owned) {
  *owned = 0;
  if (lua_type(L, idx) != LUA_TTABLE) return gr_check_rings(L, idx);
  gr_rings *r = gr_rings_new();
  if (!r) luaL_error(L, "out of memory");
  *owned = 1;
  lua_Integer nr = luaL_len(L, idx);
  for (lua_Integer i = 1; i <= nr; i++) {
    lua_geti(L, idx, i);
    if (lua_type(L, -1) != LUA_TTABLE) {
      gr_rings_free(r);
      luaL_error(L, "bad argument #%d (ring %d is not a table of numbers)", idx, (int)i);
    }
    lua_Integer n = luaL_len(L, -1);
    if (n % 2 || n < 6) {
      gr_rings_free(r);
      luaL_error(L, "bad argument #%d (ring %d needs x, y pairs of at least 3 points, got %d numbers)",
                 idx, (int)i, (int)n);
    }
    for (lua_Integer k = 1; k <= n; k += 2) {
      lua_geti(L, -1, k);
      lua_geti(L, -2, k + 1);
      int okx, oky;
      double x = lua_tonumberx(L, -2, &okx), y = lua_tonumberx(L, -1, &oky);
      lua_pop(L, 2);
      if (!okx || !oky) {
        gr_rings_free(r);
        luaL_error(L, "bad argument #%d (ring %d item %d is not a number)", idx, (int)i, (int)k);
      }
      gr_rings_point(r, x, y);
    }
    gr_rings_close(r);
    lua_pop(L, 1);
  }
  return r;
}

static const char *const HATCH_KEYS[] = {
    "spacing", "beam_offset", "contours", "contour_first", "gap", "pattern", "alternate",
    "angle", "island", "island_origin", "min_length", "laser", "cell", "z", "thin_box", NULL};

static gr_hatch_opts read_hatch_opts(lua_State *L, int idx, const char *fn) {
  check_keys(L, idx, fn, HATCH_KEYS);
  gr_hatch_opts o = gr_hatch_defaults();
  o.spacing = gr_opt_number(L, idx, "spacing", o.spacing);
  o.beam_offset = gr_opt_number(L, idx, "beam_offset", NAN);
  o.contours = gr_opt_integer(L, idx, "contours", o.contours);
  o.contour_first = gr_opt_boolean(L, idx, "contour_first", o.contour_first);
  o.gap = gr_opt_number(L, idx, "gap", o.gap);
  const char *p = gr_opt_string(L, idx, "pattern", "parallel");
  o.pattern = -1;
  for (int i = 0; PATTERN_NAMES[i]; i++)
    if (!strcmp(p, PATTERN_NAMES[i])) o.pattern = i;
  if (o.pattern < 0)
    luaL_error(L, "bad option 'pattern' (parallel, zigzag or island expected, got '%s')", p);
  o.alternate = gr_opt_boolean(L, idx, "alternate", o.alternate);
  o.angle = gr_opt_number(L, idx, "angle", o.angle);
  o.island = gr_opt_number(L, idx, "island", o.island);
  gr_opt_vec(L, idx, "island_origin", 2, o.island_origin);
  gr_opt_vec(L, idx, "thin_box", 4, o.thin_box);
  o.min_length = gr_opt_number(L, idx, "min_length", o.min_length);
  int laser = gr_opt_integer(L, idx, "laser", 1);
  if (laser < 1) luaL_error(L, "bad option 'laser' (lasers count from 1, got %d)", laser);
  o.laser = laser - 1;
  o.cell = gr_opt_number(L, idx, "cell", NAN);
  return o;
}

static void push_report(lua_State *L, const gr_hatch_report *r) {
  lua_createtable(L, 0, 9);
  lua_pushinteger(L, (lua_Integer)r->contours); lua_setfield(L, -2, "contours");
  lua_pushinteger(L, (lua_Integer)r->hatches); lua_setfield(L, -2, "hatches");
  lua_pushinteger(L, (lua_Integer)r->links); lua_setfield(L, -2, "links");
  lua_pushinteger(L, (lua_Integer)r->dropped); lua_setfield(L, -2, "dropped");
  lua_pushnumber(L, r->dropped_length); lua_setfield(L, -2, "dropped_length");
  lua_pushinteger(L, r->thin_walls); lua_setfield(L, -2, "thin_walls");
  lua_pushinteger(L, (lua_Integer)r->thin_scans); lua_setfield(L, -2, "thin_scans");
  lua_pushnumber(L, r->thin_length); lua_setfield(L, -2, "thin_length");
  lua_pushnumber(L, r->hatch_offset); lua_setfield(L, -2, "hatch_offset");
}

/* Shared by hatch.layer (contours + infill) and hatch.region (infill). */
static int hatch_common(lua_State *L, int whole) {
  const char *fn = whole ? "hatch.layer" : "hatch.region";
  gr_hatch_opts o = read_hatch_opts(L, 2, fn);
  double z = gr_opt_number(L, 2, "z", 0);
  int owned;
  gr_rings *sec = to_rings(L, 1, &owned);
  if (owned) gr_push_rings(L, sec); /* owned by the stack from here on */
  gr_layer *l = gr_layer_new(z);
  if (!l) return luaL_error(L, "out of memory");
  gr_push_layer(L, l);
  gr_hatch_report rep;
  memset(&rep, 0, sizeof rep);
  gr_err e;
  gr_err_clear(&e);
  int rc = whole ? gr_hatch_layer(sec, &o, l, &rep, &e) : gr_hatch_region(sec, &o, l, &rep, &e);
  if (rc) return gr_lua_error(L, &e);
  push_report(L, &rep);
  return 2;
}

/* gradus.hatch.layer(section, opts) -> layer, report */
static int h_layer(lua_State *L) { return hatch_common(L, 1); }
/* gradus.hatch.region(region, opts) -> layer, report */
static int h_region(lua_State *L) { return hatch_common(L, 0); }

/* gradus.hatch.angle(k, first=45, increment=67) -> degrees in [0, 360) */
static int h_angle(lua_State *L) {
  lua_Integer k = luaL_checkinteger(L, 1);
  double first = luaL_optnumber(L, 2, 45), inc = luaL_optnumber(L, 3, 67);
  luaL_argcheck(L, isfinite(first), 2, "first angle must be finite");
  luaL_argcheck(L, isfinite(inc), 3, "increment must be finite");
  lua_pushnumber(L, gr_hatch_angle((long)k, first, inc));
  return 1;
}

static const char *const VERIFY_KEYS[] = {"track", "pixel", "offset", "spacing", "contours", "clip_lo", "clip_hi", NULL};

/* gradus.hatch.verify(section, layer, {track=, pixel=, offset=, spacing=,
 * contours=}) -> {pore=, overmelt=, max_dev=, mean_dev=, solid_area=, ...} */
static int h_verify(lua_State *L) {
  gr_layer *l = gr_check_layer(L, 2);
  check_keys(L, 3, "hatch.verify", VERIFY_KEYS);
  gr_verify_opts o = gr_verify_defaults();
  o.track = gr_opt_number(L, 3, "track", NAN);
  if (isnan(o.track))
    return luaL_error(L, "hatch.verify: option 'track' (melt track width, mm) is required");
  o.pixel = gr_opt_number(L, 3, "pixel", NAN);
  o.offset = gr_opt_number(L, 3, "offset", NAN);
  o.spacing = gr_opt_number(L, 3, "spacing", NAN);
  o.contours = gr_opt_integer(L, 3, "contours", 1);
  o.clip = gr_opt_vec(L, 3, "clip_lo", 2, o.clip_lo) & gr_opt_vec(L, 3, "clip_hi", 2, o.clip_hi);
  int owned;
  gr_rings *sec = to_rings(L, 1, &owned);
  if (owned) gr_push_rings(L, sec);
  gr_verify_result r;
  gr_err e;
  gr_err_clear(&e);
  if (gr_verify_layer(sec, l, &o, &r, &e)) return gr_lua_error(L, &e);
  lua_createtable(L, 0, 14);
  lua_pushnumber(L, r.pore); lua_setfield(L, -2, "pore");
  lua_pushnumber(L, r.overmelt); lua_setfield(L, -2, "overmelt");
  lua_pushnumber(L, r.max_dev); lua_setfield(L, -2, "max_dev");
  lua_pushnumber(L, r.mean_dev); lua_setfield(L, -2, "mean_dev");
  lua_pushnumber(L, r.solid_area); lua_setfield(L, -2, "solid_area");
  lua_pushnumber(L, r.melt_area); lua_setfield(L, -2, "melt_area");
  lua_pushinteger(L, (lua_Integer)r.contour_points); lua_setfield(L, -2, "contour_points");
  lua_pushinteger(L, (lua_Integer)r.thin_points); lua_setfield(L, -2, "thin_points");
  lua_pushinteger(L, (lua_Integer)r.thin_scans); lua_setfield(L, -2, "thin_scans");
  lua_pushnumber(L, r.thin_length); lua_setfield(L, -2, "thin_length");
  lua_pushnumber(L, r.hatch_length); lua_setfield(L, -2, "hatch_length");
  lua_pushnumber(L, r.hatch_outside); lua_setfield(L, -2, "hatch_outside");
  lua_pushinteger(L, r.nx); lua_setfield(L, -2, "nx");
  lua_pushinteger(L, r.ny); lua_setfield(L, -2, "ny");
  return 1;
}

/* ---- layers ---- */

/* gradus.layer.new(z = 0) -> empty layer */
static int l_new(lua_State *L) {
  double z = luaL_optnumber(L, 1, 0);
  luaL_argcheck(L, isfinite(z), 1, "z must be finite");
  gr_layer *l = gr_layer_new(z);
  if (!l) return luaL_error(L, "out of memory");
  gr_push_layer(L, l);
  return 1;
}

/* l:stats() -> {contour = {vectors=, length=, blocks=}, hatch = ..., edge = ...,
 * jumps=, jump_length=, blocks=, thin_walls=} */
static int l_stats(lua_State *L) {
  gr_layer *l = gr_check_layer(L, 1);
  gr_layer_stats s;
  gr_layer_stats_get(l, &s);
  size_t nb[GR_NKINDS] = {0};
  for (size_t i = 0; i < l->nb; i++)
    if (l->b[i].kind >= 0 && l->b[i].kind < GR_NKINDS) nb[l->b[i].kind]++;
  lua_createtable(L, 0, 8);
  for (int k = 0; k < GR_NKINDS; k++) {
    lua_createtable(L, 0, 3);
    lua_pushinteger(L, (lua_Integer)s.vectors[k]); lua_setfield(L, -2, "vectors");
    lua_pushnumber(L, s.length[k]); lua_setfield(L, -2, "length");
    lua_pushinteger(L, (lua_Integer)nb[k]); lua_setfield(L, -2, "blocks");
    lua_setfield(L, -2, KIND_NAMES[k]);
  }
  lua_pushinteger(L, (lua_Integer)s.jumps); lua_setfield(L, -2, "jumps");
  lua_pushnumber(L, s.jump_length); lua_setfield(L, -2, "jump_length");
  lua_pushinteger(L, (lua_Integer)l->nb); lua_setfield(L, -2, "blocks");
  lua_pushinteger(L, l->thin_walls); lua_setfield(L, -2, "thin_walls");
  return 1;
}

/* l:blocks() -> array of {kind=, shape=, dir=, laser= (1-based), thin= (thin-wall
 * centre line), region= (core, skin, thin, downskin, upskin: regions.h), id=
 * (the CLI build-style id), points={x1, y1, ...}} */
static int l_blocks(lua_State *L) {
  gr_layer *l = gr_check_layer(L, 1);
  lua_createtable(L, (int)l->nb, 0);
  for (size_t i = 0; i < l->nb; i++) {
    const gr_block *b = &l->b[i];
    lua_createtable(L, 0, 5);
    lua_pushstring(L, b->kind >= 0 && b->kind < GR_NKINDS ? KIND_NAMES[b->kind] : "?");
    lua_setfield(L, -2, "kind");
    lua_pushstring(L, b->shape >= 0 && b->shape <= GR_SEGMENTS ? SHAPE_NAMES[b->shape] : "?");
    lua_setfield(L, -2, "shape");
    lua_pushinteger(L, b->dir); lua_setfield(L, -2, "dir");
    lua_pushboolean(L, b->dir == GR_DIR_THIN); lua_setfield(L, -2, "thin");
    lua_pushinteger(L, b->laser + 1); lua_setfield(L, -2, "laser");
    lua_pushstring(L, gr_region_name(b->region)); lua_setfield(L, -2, "region");
    lua_pushinteger(L, gr_style_id(b)); lua_setfield(L, -2, "id");
    lua_createtable(L, (int)(2 * b->n), 0);
    for (size_t k = 0; k < 2 * b->n; k++) {
      lua_pushnumber(L, l->xy[2 * b->start + k]);
      lua_rawseti(L, -2, (lua_Integer)k + 1);
    }
    lua_setfield(L, -2, "points");
    lua_rawseti(L, -2, (lua_Integer)i + 1);
  }
  return 1;
}

/* l:z() -> z (mm) */
static int l_z(lua_State *L) {
  lua_pushnumber(L, gr_check_layer(L, 1)->z);
  return 1;
}

/* l:bounds() -> xmin, ymin, xmax, ymax (nil for an empty layer) */
static int l_bounds(lua_State *L) {
  gr_layer *l = gr_check_layer(L, 1);
  if (!l->npts) { lua_pushnil(L); return 1; }
  double lo[2], hi[2];
  gr_layer_bounds(l, lo, hi);
  lua_pushnumber(L, lo[0]); lua_pushnumber(L, lo[1]);
  lua_pushnumber(L, hi[0]); lua_pushnumber(L, hi[1]);
  return 4;
}

/* l:translate(dx, dy) -> l (in place) */
static int l_translate(lua_State *L) {
  gr_layer *l = gr_check_layer(L, 1);
  double dx = luaL_checknumber(L, 2), dy = luaL_checknumber(L, 3);
  luaL_argcheck(L, isfinite(dx), 2, "dx must be finite");
  luaL_argcheck(L, isfinite(dy), 3, "dy must be finite");
  for (size_t k = 0; k < l->npts; k++) { l->xy[2 * k] += dx; l->xy[2 * k + 1] += dy; }
  lua_settop(L, 1);
  return 1;
}

/* l:append(other, dx = 0, dy = 0) -> l */
static int l_append(lua_State *L) {
  gr_layer *l = gr_check_layer(L, 1), *o = gr_check_layer(L, 2);
  double dx = luaL_optnumber(L, 3, 0), dy = luaL_optnumber(L, 4, 0);
  luaL_argcheck(L, l != o, 2, "cannot append a layer to itself");
  if (gr_layer_append(l, o, dx, dy)) return luaL_error(L, "out of memory");
  lua_settop(L, 1);
  return 1;
}

/* l:add(kind, shape, points, laser = 1) -> l. Closed blocks get their first
 * point repeated if it is not, and dir from their orientation (1 CCW, 0 CW);
 * open ones dir 2. */
static int l_add(lua_State *L) {
  gr_layer *l = gr_check_layer(L, 1);
  int kind = luaL_checkoption(L, 2, NULL, KIND_NAMES);
  int shape = luaL_checkoption(L, 3, NULL, SHAPE_NAMES);
  luaL_checktype(L, 4, LUA_TTABLE);
  lua_Integer laser = luaL_optinteger(L, 5, 1);
  luaL_argcheck(L, laser >= 1, 5, "lasers count from 1");
  lua_Integer n = luaL_len(L, 4);
  if (n % 2) return luaL_argerror(L, 4, lua_pushfstring(L, "x, y pairs expected, got %d numbers", (int)n));
  size_t np = (size_t)n / 2;
  size_t need = shape == GR_SEGMENTS ? 2 : shape == GR_CLOSED ? 3 : 2;
  if (np < need)
    return luaL_argerror(L, 4, lua_pushfstring(L, "a %s block needs at least %d points, got %d",
                                               SHAPE_NAMES[shape], (int)need, (int)np));
  if (shape == GR_SEGMENTS && np % 2)
    return luaL_argerror(L, 4, lua_pushfstring(L, "segments need an even number of points, got %d", (int)np));
  double *xy = lua_newuserdatauv(L, (np + 1) * 2 * sizeof *xy, 0);
  for (lua_Integer k = 1; k <= n; k++) {
    lua_geti(L, 4, k);
    int ok;
    xy[k - 1] = lua_tonumberx(L, -1, &ok);
    lua_pop(L, 1);
    if (!ok || !isfinite(xy[k - 1]))
      return luaL_argerror(L, 4, lua_pushfstring(L, "item %d is not a finite number", (int)k));
  }
  int dir = shape == GR_OPEN ? 2 : 0;
  if (shape == GR_CLOSED) {
    if (xy[0] != xy[2 * np - 2] || xy[1] != xy[2 * np - 1]) {
      xy[2 * np] = xy[0];
      xy[2 * np + 1] = xy[1];
      np++;
    }
    double a = 0;
    for (size_t k = 0; k + 1 < np; k++) a += xy[2 * k] * xy[2 * k + 3] - xy[2 * k + 2] * xy[2 * k + 1];
    dir = a > 0 ? 1 : 0;
  }
  if (gr_layer_add(l, shape, kind, (int)laser - 1, dir, xy, np)) return luaL_error(L, "out of memory");
  lua_settop(L, 1);
  return 1;
}

static int l_tostring(lua_State *L) {
  gr_layer *l = gr_check_layer(L, 1);
  gr_layer_stats s;
  gr_layer_stats_get(l, &s);
  size_t nc = 0;
  for (size_t i = 0; i < l->nb; i++) nc += l->b[i].kind == GR_CONTOUR;
  char buf[512];
  int n = snprintf(buf, sizeof buf, "layer z=%.6g: %zu contours (%.3f mm), %zu hatches (%.3f mm)", l->z,
                   nc, s.length[GR_CONTOUR], s.vectors[GR_HATCH], s.length[GR_HATCH]);
  if (s.vectors[GR_EDGE] && n > 0 && n < 400)
    n += snprintf(buf + n, sizeof buf - (size_t)n, ", %zu edge vectors (%.3f mm)", s.vectors[GR_EDGE],
                  s.length[GR_EDGE]);
  if (l->thin_walls && n > 0 && n < 450)
    snprintf(buf + n, sizeof buf - (size_t)n, ", %d thin walls", l->thin_walls);
  lua_pushstring(L, buf);
  return 1;
}

int gr_open_hatch(lua_State *L) {
  static const luaL_Reg hatch_fns[] = {
      {"layer", h_layer}, {"region", h_region}, {"angle", h_angle}, {"verify", h_verify}, {NULL, NULL}};
  static const luaL_Reg layer_fns[] = {{"new", l_new}, {NULL, NULL}};
  static const luaL_Reg layer_methods[] = {
      {"stats", l_stats},   {"blocks", l_blocks}, {"z", l_z},         {"bounds", l_bounds},
      {"translate", l_translate}, {"append", l_append}, {"add", l_add}, {"__tostring", l_tostring},
      {NULL, NULL}};
  luaL_newlib(L, hatch_fns);
  lua_setfield(L, -2, "hatch");
  luaL_newlib(L, layer_fns);
  lua_setfield(L, -2, "layer");
  gr_add_methods(L, GR_MT_LAYER, layer_methods);
  return 0;
}
