/* bind_regions.c: Lua binding of regions.h (regions with their own build
 * styles).
 *   job:regions{skin = 900, thin = 600, downskin = 1400, upskin = 900, down = 3, up = 3,
 *               downskin_hatch = 0.025}
 * Each region named gets its own CLI ids; its value is its scan speed (mm/s,
 * for the time estimates). down / up: layers looked at below / above.
 * <region>_hatch: that hatched region's own hatch spacing, mm. The
 * stats of job:run then hold `regions` (gr_regions_push_stats). */
#include <math.h>
#include <string.h>
#include "bind.h"
#include "regions.h"

/* job:regions{...} (job: the gradus.job userdata, whose first member is the job) */
int gr_l_job_regions(lua_State *L) {
  gr_job **pj = luaL_checkudata(L, 1, "gradus.job");
  if (!*pj) return luaL_argerror(L, 1, "job is closed");
  luaL_checktype(L, 2, LUA_TTABLE);
  gr_regions_opts o;
  memset(&o, 0, sizeof o);
  o.down = o.up = 3;
  lua_pushnil(L);
  while (lua_next(L, 2)) {
    const char *k = lua_type(L, -2) == LUA_TSTRING ? lua_tostring(L, -2) : "?";
    int r = 1;
    while (r < GR_NREGIONS && strcmp(k, gr_region_name(r))) r++;
    if (!lua_isnumber(L, -1)) return luaL_error(L, "job:regions: '%s' must be a number", k);
    double v = lua_tonumber(L, -1);
    size_t kl = strlen(k);
    int hr = 0; /* "<region>_hatch": that region's hatch spacing, mm */
    while (hr < GR_NREGIONS && !(kl == strlen(gr_region_name(hr)) + 6 && !strncmp(k, gr_region_name(hr), kl - 6) &&
                                 !strcmp(k + kl - 6, "_hatch")))
      hr++;
    if (r < GR_NREGIONS) {
      o.mask |= 1 << r;
      o.speed[r] = v;
    } else if (hr < GR_NREGIONS) {
      o.hatch[hr] = v;
    } else if (!strcmp(k, "skin_contours")) {
      if (!(v >= 0 && v <= 20 && v == floor(v))) return luaL_error(L, "job:regions: 'skin_contours' must be a whole number in 0..20");
      o.skin_contours = (int)v;
    } else if (!strcmp(k, "down") || !strcmp(k, "up")) {
      if (!(v >= 1 && v <= 64 && v == floor(v))) return luaL_error(L, "job:regions: '%s' must be a whole number of layers in 1..64", k);
      *(!strcmp(k, "down") ? &o.down : &o.up) = (int)v;
    } else {
      return luaL_error(L, "job:regions: unknown key '%s' (skin, thin, downskin, upskin, down, up, <region>_hatch, skin_contours)", k);
    }
    lua_pop(L, 1);
  }
  gr_err e;
  gr_err_clear(&e);
  if (gr_job_set_regions(*pj, &o, &e)) return gr_lua_error(L, &e);
  return 0;
}

static void setn(lua_State *L, const char *k, double v) { lua_pushnumber(L, v); lua_setfield(L, -2, k); }

void gr_regions_push_stats(lua_State *L, const gr_job *j, const gr_job_stats *st) {
  int mask = gr_regions_mask(j);
  if (!mask) return;
  lua_newtable(L);
  for (int r = 0; r < GR_NREGIONS; r++) {
    if (r && !(mask >> r & 1)) continue;
    lua_newtable(L);
    lua_pushinteger(L, (lua_Integer)st->region_vectors[r]);
    lua_setfield(L, -2, "vectors");
    setn(L, "length", st->region_length[r]);
    setn(L, "scan_time_s", st->region_time[r]);
    if (r != GR_THIN) setn(L, "hatch", gr_regions_hatch(j, r));
    lua_setfield(L, -2, gr_region_name(r));
  }
  lua_setfield(L, -2, "regions");
}
