/* lasers.c: laser assignment, time estimates, statistics, see lasers.h. */
#include "lasers.h"
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define EPS 1e-9

/* Estimated scan time of a voxel slot on laser l (s). */
static double est_time(const gr_machine *m, int l, double lc, double lh) {
  return lc / m->speed[l][GR_CONTOUR] + lh / m->speed[l][GR_HATCH];
}

int gr_lasers_reach_box(const gr_machine *m, int l, const double lo[2], const double hi[2]) {
  return !(lo[0] < m->lo[l][0] - EPS || lo[1] < m->lo[l][1] - EPS || hi[0] > m->hi[l][0] + EPS ||
           hi[1] > m->hi[l][1] + EPS);
}

/* Can laser l scan the whole voxel with min corner o? */
static int laser_reaches(const gr_machine *m, int l, const double o[3], const double cell[3]) {
  double hi[2] = {o[0] + cell[0], o[1] + cell[1]};
  return gr_lasers_reach_box(m, l, o, hi);
}

/* Assign lasers to the voxel slots of a layer: fixed ones as given; the
 * others by longest-processing-time-first onto the laser that would finish
 * first among those that reach the voxel. */
int gr_lasers_check(const gr_machine *m, const gr_grid *grid, const int *vlaser, const int *vox, int nslot,
                    gr_err *e) {
  for (int q = 0; q < nslot; q++) {
    int v = vox[q], any = 0;
    double o[3];
    gr_grid_origin(grid, v, o);
    if (vlaser[v] >= 0 || m->n == 1) {
      int l = vlaser[v] >= 0 ? vlaser[v] : 0;
      if (!laser_reaches(m, l, o, grid->cell))
        return gr_fail(e, GR_EARG, "laser %d does not reach voxel [%g, %g] x [%g, %g] mm: the machine's laser fields do not cover the part",
                       l + 1, o[0], o[0] + grid->cell[0], o[1], o[1] + grid->cell[1]);
      continue;
    }
    for (int l = 0; l < m->n && !any; l++) any = laser_reaches(m, l, o, grid->cell);
    if (!any)
      return gr_fail(e, GR_EARG, "no laser reaches voxel [%g, %g] x [%g, %g] mm: the machine's laser fields do not cover the part",
                     o[0], o[0] + grid->cell[0], o[1], o[1] + grid->cell[1]);
  }
  return GR_OK;
}

int gr_lasers_assign(const gr_machine *m, const gr_grid *grid, const int *vlaser, const int *vox, int nslot,
                     const double *lc, const double *lh, int *las, gr_err *e) {
  int rc = gr_lasers_check(m, grid, vlaser, vox, nslot, e);
  if (rc) return rc;
  double load[GR_MAX_LASERS] = {0};
  int *ord = malloc((size_t)(nslot > 0 ? nslot : 1) * sizeof *ord);
  if (!ord) return gr_fail(e, GR_EMEM, "out of memory");
  int nfree = 0;
  for (int q = 0; q < nslot; q++) {
    int v = vox[q];
    if (vlaser[v] >= 0 || m->n == 1) {
      las[q] = vlaser[v] >= 0 ? vlaser[v] : 0;
      load[las[q]] += est_time(m, las[q], lc[q], lh[q]);
    } else {
      ord[nfree++] = q;
    }
  }
  /* sort free slots by decreasing time (insertion sort: rows are small) */
  for (int a = 1; a < nfree; a++) {
    int x = ord[a], b = a;
    double tx = lc[x] + lh[x];
    while (b > 0 && lc[ord[b - 1]] + lh[ord[b - 1]] < tx) { ord[b] = ord[b - 1]; b--; }
    ord[b] = x;
  }
  for (int a = 0; a < nfree; a++) {
    int q = ord[a], v = vox[q];
    double o[3];
    gr_grid_origin(grid, v, o);
    int best = -1;
    double bt = INFINITY;
    for (int l = 0; l < m->n; l++) {
      if (!laser_reaches(m, l, o, grid->cell)) continue;
      double t = load[l] + est_time(m, l, lc[q], lh[q]);
      if (t < bt) { bt = t; best = l; }
    }
    las[q] = best; /* >= 0: gr_lasers_check passed */
    load[best] = bt;
  }
  free(ord);
  return GR_OK;
}

void gr_lasers_account(const gr_machine *m, const gr_layer *l, gr_job_stats *st) {
  double len[GR_MAX_LASERS][GR_NKINDS];
  double jl[GR_MAX_LASERS], rt[GR_MAX_LASERS]; /* rt: marking time of region vectors (regions.h) */
  size_t nj[GR_MAX_LASERS], nb[GR_MAX_LASERS];
  double px[GR_MAX_LASERS], py[GR_MAX_LASERS];
  int have[GR_MAX_LASERS];
  memset(len, 0, sizeof len);
  memset(jl, 0, sizeof jl);
  memset(rt, 0, sizeof rt);
  memset(nj, 0, sizeof nj);
  memset(nb, 0, sizeof nb);
  memset(have, 0, sizeof have);
  for (size_t b = 0; b < l->nb; b++) {
    const gr_block *bk = &l->b[b];
    int la = bk->laser, k = bk->kind, rg = bk->region >= 0 && bk->region < GR_NREGIONS ? bk->region : 0;
    if (la < 0 || la >= m->n || bk->n < 2) continue;
    double blen = gr_block_length(l, bk);
    st->region_vectors[rg] += bk->shape == GR_SEGMENTS ? bk->n / 2 : bk->n - 1;
    st->region_length[rg] += blen;
    double other = 0, *acc = &len[la][k]; /* a region's own speed: kept apart from the core's sums */
    if (rg && m->rspeed[rg] > 0) {
      acc = &other;
      rt[la] += blen / m->rspeed[rg];
      st->region_time[rg] += blen / m->rspeed[rg];
      st->length[k] += blen;
      st->laser_length[la] += blen;
    } else {
      st->region_time[rg] += blen / m->speed[la][k];
    }
    const double *p = l->xy + 2 * bk->start;
    nb[la]++;
    size_t step = bk->shape == GR_SEGMENTS ? 2 : bk->n;
    for (size_t q = 0; q + 1 < bk->n; q += step) {
      double d = gr_len2d(p[2 * q] - px[la], p[2 * q + 1] - py[la]);
      if (have[la] && d > 1e-9) { nj[la]++; jl[la] += d; }
      have[la] = 1;
      size_t last = bk->shape == GR_SEGMENTS ? q + 1 : bk->n - 1;
      px[la] = p[2 * last];
      py[la] = p[2 * last + 1];
      if (bk->shape == GR_SEGMENTS) {
        st->vectors[k]++;
        *acc += gr_len2d(p[2 * q + 2] - p[2 * q], p[2 * q + 3] - p[2 * q + 1]);
      } else {
        st->vectors[k] += bk->n - 1;
        for (size_t r = 0; r + 1 < bk->n; r++) *acc += gr_len2d(p[2 * r + 2] - p[2 * r], p[2 * r + 3] - p[2 * r + 1]);
      }
    }
  }
  double makespan = 0, total = 0;
  for (int la = 0; la < m->n; la++) {
    double t = jl[la] / m->jump_speed + nj[la] * m->jump_delay + nb[la] * m->polygon_delay + rt[la];
    st->jump_time += t;
    for (int k = 0; k < GR_NKINDS; k++) {
      t += len[la][k] / m->speed[la][k];
      st->length[k] += len[la][k];
      st->laser_length[la] += len[la][k];
    }
    st->laser_time[la] += t;
    st->jumps += nj[la];
    st->jump_length += jl[la];
    if (t > makespan) makespan = t;
    total += t;
  }
  st->build_time += makespan + m->recoat_time;
  st->recoat_time += m->recoat_time;
  st->balanced_time += total / m->n + m->recoat_time;
  st->thin_walls += l->thin_walls;
  st->short_loops += l->short_loops;
  st->short_length += l->short_length;
  st->solid_area += l->area;
}

void gr_lasers_add(gr_job_stats *st, const gr_job_stats *l) {
  for (int k = 0; k < GR_NKINDS; k++) {
    st->vectors[k] += l->vectors[k];
    st->length[k] += l->length[k];
  }
  for (int la = 0; la < GR_MAX_LASERS; la++) {
    st->laser_time[la] += l->laser_time[la];
    st->laser_length[la] += l->laser_length[la];
  }
  for (int r = 0; r < GR_NREGIONS; r++) {
    st->region_vectors[r] += l->region_vectors[r];
    st->region_length[r] += l->region_length[r];
    st->region_time[r] += l->region_time[r];
  }
  st->jumps += l->jumps;
  st->jump_length += l->jump_length;
  st->build_time += l->build_time;
  st->jump_time += l->jump_time;
  st->recoat_time += l->recoat_time;
  st->balanced_time += l->balanced_time;
  st->thin_walls += l->thin_walls;
  st->short_loops += l->short_loops;
  st->short_length += l->short_length;
  st->solid_area += l->solid_area;
}

