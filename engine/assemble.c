/* assemble.c: a part layer from the templates, see assemble.h. */
#include "assemble.h"
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "classify.h"
#include "clip.h"
#include "facestep.h"
#include "facing.h"
#include "hatch.h"
#include "lasers.h"
#include "regions.h"
#include "skinring.h"

typedef gr_asm_seg seg; /* stitch.h */


void gr_asm_scratch_free(gr_asm_scratch *s) {
  gr_rings_free(s->rg);
  gr_layer_free(s->fl);
  free(s->cbuf);
  gr_layer_free(s->hl);
  gr_layer_free(s->cont);
  free(s->segs);
  free(s->segs2);
  free(s->bucket);
  free(s->vtime);
  free(s->vlas);
  free(s->vseg0);
  free(s->vseg1);
  free(s->vcont0);
  free(s->vcont1);
  free(s->pts);
  free(s->link);
  gr_fstep_cache_free(s->fs);
}

int gr_asm_scratch_init(gr_asm_scratch *s, int nrow) {
  memset(s, 0, sizeof *s);
  s->rg = gr_rings_new();
  s->hl = gr_layer_new(0);
  s->cont = gr_layer_new(0);
  s->fl = gr_layer_new(0);
  s->vtime = calloc(nrow, sizeof *s->vtime);
  s->vlas = calloc(nrow, sizeof *s->vlas);
  s->vseg0 = calloc(nrow, sizeof(size_t));
  s->vseg1 = calloc(nrow, sizeof(size_t));
  s->vcont0 = calloc(nrow, sizeof(size_t));
  s->vcont1 = calloc(nrow, sizeof(size_t));
  s->fs = gr_fstep_cache_new();
  if (!s->fs || !s->rg || !s->hl || !s->cont || !s->fl || !s->vtime || !s->vlas || !s->vseg0 || !s->vseg1 ||
      !s->vcont0 || !s->vcont1)
    return GR_EMEM;
  return GR_OK;
}

static int seg_cmp(const void *a, const void *b) {
  const seg *p = a, *q = b;
  if (p->laser != q->laser) return p->laser < q->laser ? -1 : 1;
  if (p->line != q->line) return p->line < q->line ? -1 : 1;
  return (p->s0 > q->s0) - (p->s0 < q->s0);
}

/* Order the layer's segments as seg_cmp does, stably: a counting sort on
 * (laser, line), then insertion sort by s0 within a line (a line crosses
 * one row of voxels, so few segments share it). qsort when the lines are
 * too sparse for buckets. */
static int sort_segs(gr_asm_scratch *s, gr_err *e) {
  size_t n = s->nseg;
  if (n < 2) return GR_OK;
  long lo = LONG_MAX, hi = LONG_MIN;
  int lmax = 0;
  for (size_t r = 0; r < n; r++) {
    if (s->segs[r].line < lo) lo = s->segs[r].line;
    if (s->segs[r].line > hi) hi = s->segs[r].line;
    if (s->segs[r].laser > lmax) lmax = s->segs[r].laser;
  }
  size_t nl = (size_t)(hi - lo) + 1, nb = nl * (size_t)(lmax + 1);
  if (hi - lo > 4 * (long)n + 4096 || nb > 8 * n + 65536) {
    qsort(s->segs, n, sizeof *s->segs, seg_cmp);
    return GR_OK;
  }
  if (gr_grow(&s->bucket, &s->capbucket, nb + 1, sizeof *s->bucket) ||
      gr_grow(&s->segs2, &s->capseg2, n, sizeof *s->segs2))
    return gr_fail(e, GR_EMEM, "out of memory");
  size_t *c = s->bucket;
  memset(c, 0, (nb + 1) * sizeof *c);
  for (size_t r = 0; r < n; r++) c[(size_t)s->segs[r].laser * nl + (size_t)(s->segs[r].line - lo) + 1]++;
  for (size_t b = 0; b < nb; b++) c[b + 1] += c[b];
  for (size_t r = 0; r < n; r++) s->segs2[c[(size_t)s->segs[r].laser * nl + (size_t)(s->segs[r].line - lo)]++] = s->segs[r];
  /* c[b] is now the end of bucket b */
  for (size_t b = 0, a = 0; b < nb; a = c[b++])
    for (size_t r = a + 1; r < c[b]; r++) {
      seg x = s->segs2[r];
      size_t q = r;
      while (q > a && s->segs2[q - 1].s0 > x.s0) { s->segs2[q] = s->segs2[q - 1]; q--; }
      s->segs2[q] = x;
    }
  seg *t = s->segs;
  size_t tc = s->capseg;
  s->segs = s->segs2;
  s->capseg = s->capseg2;
  s->segs2 = t;
  s->capseg2 = tc;
  return GR_OK;
}


/* Hatch one voxel: its template region translated to global coordinates,
 * lines of the global family at angle a, clipped to the voxel square. */
/* The voxel rectangle [0, Lx] x [0, Ly] with the sides in mask moved in by c (mm). */
static void side_box(const gr_job *j, int mask, double c, double lo[2], double hi[2]) {
  const double *L = j->o.cell;
  lo[0] = (mask & 1) ? c : 0;
  hi[0] = (mask & 2) ? L[0] - c : L[0];
  lo[1] = (mask & 4) ? c : 0;
  hi[1] = (mask & 8) ? L[1] - c : L[1];
}

/* Offset of the hatch region from the section boundary (hatch.h), mm. */
static double hatch_offset(const gr_job *j) {
  double gap = gr_hatch_defaults().gap;
  int n = j->o.contours;
  return n == 0 ? j->o.beam_offset + gap : j->o.beam_offset + (n - 1) * j->o.hatch + gap;
}

/* Contours of boundary voxel tl (sides in mask): the template's cut by the
 * sides moved in by b, plus the side segments; voxel-local, into s->fl. */
static int boundary_contours(const gr_job *j, gr_asm_scratch *s, const gr_tlayer *tl, int mask) {
  double lo[2], hi[2], lof[2], hif[2];
  side_box(j, mask, j->o.beam_offset, lof, hif);
  /* the contours kept to GR_FACE_EPS outside the moved sides (template.h) */
  side_box(j, mask, j->o.beam_offset - GR_FACE_EPS, lo, hi);
  gr_layer_clear(s->fl, 0);
  for (size_t b = 0; b < tl->paths->nb; b++) {
    const gr_block *bk = &tl->paths->b[b];
    if (gr_clip_poly(tl->paths->xy + 2 * bk->start, bk->n, bk->shape == GR_CLOSED, bk->kind, bk->dir, lo, hi, s->fl,
                  &s->cbuf, &s->capcbuf))
      return GR_EMEM;
  }
  for (size_t b = 0; tl->faces && b < tl->faces->nb; b++) {
    const gr_block *bk = &tl->faces->b[b];
    if (!((mask >> bk->laser) & 1)) continue;
    if (gr_clip_poly(tl->faces->xy + 2 * bk->start, bk->n, 0, bk->kind, 2, lof, hif, s->fl, &s->cbuf, &s->capcbuf))
      return GR_EMEM;
  }
  s->fl->thin_walls = tl->paths->thin_walls;
  return GR_OK;
}

static int hatch_voxel(gr_job *j, gr_asm_scratch *s, const gr_tlayer *tl, const double o[3],
                       double a, int slot, int mask, gr_err *e) {
  if (tl->region->nrings == 0) return GR_OK;
  if (gr_rings_copy(s->rg, tl->region)) return gr_fail(e, GR_EMEM, "out of memory");
  gr_rings_translate(s->rg, o[0], o[1]);
  gr_layer_clear(s->hl, 0);
  gr_hatch_opts ho = gr_hatch_defaults();
  double d0 = gr_regions_line(j); /* the job's spacing, or finer for regions of their own (regions.h) */
  ho.spacing = d0;
  ho.angle = a;
  ho.pattern = GR_PARALLEL;
  ho.alternate = 0;
  ho.contours = 0;
  if (gr_hatch_region(s->rg, &ho, s->hl, NULL, e)) return e->code;
  double ca = cos(a * M_PI / 180), sa = sin(a * M_PI / 180);
  double lo[2], hi[2];
  side_box(j, mask, hatch_offset(j), lo, hi);
  for (int k = 0; k < 2; k++) { lo[k] += o[k]; hi[k] += o[k]; }
  for (size_t b = 0; b < s->hl->nb; b++) {
    const gr_block *bk = &s->hl->b[b];
    const double *p = s->hl->xy + 2 * bk->start;
    for (size_t q = 0; q + 1 < bk->n; q += 2) {
      double t0, t1, px = p[2 * q], py = p[2 * q + 1], qx = p[2 * q + 2], qy = p[2 * q + 3];
      if (!gr_clip_seg(px, py, qx, qy, lo, hi, &t0, &t1)) continue;
      double ax = px + t0 * (qx - px), ay = py + t0 * (qy - py);
      double bx = px + t1 * (qx - px), by = py + t1 * (qy - py);
      double sa0 = ax * ca + ay * sa, sb0 = bx * ca + by * sa;
      if (fabs(sb0 - sa0) < 1e-9) continue;
      if (gr_grow(&s->segs, &s->capseg, s->nseg + 1, sizeof *s->segs)) return gr_fail(e, GR_EMEM, "out of memory");
      seg *sg = &s->segs[s->nseg++];
      if (sb0 < sa0) { double tx = ax, ty = ay; ax = bx; ay = by; bx = tx; by = ty; double ts = sa0; sa0 = sb0; sb0 = ts; }
      sg->x0 = ax; sg->y0 = ay; sg->x1 = bx; sg->y1 = by;
      sg->s0 = sa0; sg->s1 = sb0;
      sg->line = lround((-ax * sa + ay * ca) / d0);
      sg->laser = 0;
      sg->voxel = slot;
      sg->region = GR_CORE;
    }
  }
  return GR_OK;
}

static int triple_cmp(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

/* A closed contour shorter than the melt track `track` (mm) is not worth
 * scanning: returns 1 and counts it in l (short_loops, short_length). */
static int short_loop(const double *p, size_t n, double track, gr_layer *l) {
  double len = 0;
  for (size_t k = 0; k + 1 < n; k++) { /* the partial sums only grow: stop once long enough */
    len += hypot(p[2 * k + 2] - p[2 * k], p[2 * k + 3] - p[2 * k + 1]);
    if (len >= track) return 0;
  }
  if (len >= track) return 0;
  l->short_loops++;
  l->short_length += len;
  return 1;
}

/* Emit the joined pieces of s->cont blocks [b0, b0 + n) (links in s->link):
 * closed blocks as they are; chains from heads, then cycles, each scanned by
 * one laser or split between lasers (stitch.h). */
static int emit_chains(gr_asm_scratch *s, size_t b0, size_t n, double track, gr_layer *out, const int *slot_laser,
                       const gr_machine *mach, long *split, gr_err *e) {
  gr_layer *c = s->cont;
  long *next = s->link, *prev = s->link + n, *used = s->link + 2 * n;
  size_t *ps = malloc((n + 1) * sizeof *ps);
  int *pl = malloc(n * sizeof *pl);
  if (!ps || !pl) { free(ps); free(pl); return gr_fail(e, GR_EMEM, "out of memory"); }
  int rc = GR_OK;
  for (int pass = 0; pass < 2 && rc == GR_OK; pass++) {
    for (size_t i = 0; i < n && rc == GR_OK; i++) {
      const gr_block *bk = &c->b[b0 + i];
      if (used[i]) continue;
      if (bk->shape != GR_OPEN) {
        if (pass == 0) {
          used[i] = 1;
          if (bk->shape == GR_CLOSED && short_loop(c->xy + 2 * bk->start, bk->n, track, out)) continue;
          rc = gr_layer_add(out, bk->shape, bk->kind, slot_laser[bk->laser], bk->dir, c->xy + 2 * bk->start, bk->n);
        }
        continue;
      }
      if (pass == 0 && prev[i] >= 0) continue; /* not a head */
      /* walk the chain */
      size_t m = 0, np = 0;
      long q = (long)i;
      int closed = 0;
      while (q >= 0 && !used[q] && rc == GR_OK) {
        used[q] = 1;
        const gr_block *pb = &c->b[b0 + q];
        size_t skip = m > 0 ? 1 : 0; /* drop the shared joint point */
        if (gr_grow(&s->pts, &s->cappts, m + pb->n, 2 * sizeof(double))) { rc = GR_EMEM; break; }
        if (skip) { /* average the joint: both ends are within tol */
          s->pts[2 * (m - 1)] = 0.5 * (s->pts[2 * (m - 1)] + c->xy[2 * pb->start]);
          s->pts[2 * (m - 1) + 1] = 0.5 * (s->pts[2 * (m - 1) + 1] + c->xy[2 * pb->start + 1]);
        }
        ps[np] = m - skip;
        pl[np++] = slot_laser[pb->laser];
        memcpy(s->pts + 2 * m, c->xy + 2 * (pb->start + skip), (pb->n - skip) * 2 * sizeof(double));
        m += pb->n - skip;
        q = next[q];
        if (q == (long)i) closed = 1;
      }
      if (rc) break;
      /* an open chain whose ends meet within a melt track is a loop whose tiny excursion across a
       * voxel border the neighbour's grid did not see (e.g. where the lattice grazes the skin):
       * closed with the short step between its ends */
      if (!closed && m > 2 && bk->dir != GR_DIR_THIN &&
          hypot(s->pts[2 * (m - 1)] - s->pts[0], s->pts[2 * (m - 1) + 1] - s->pts[1]) <= track) {
        if (gr_grow(&s->pts, &s->cappts, m + 1, 2 * sizeof(double))) { rc = GR_EMEM; break; }
        s->pts[2 * m] = s->pts[0], s->pts[2 * m + 1] = s->pts[1];
        m++;
        closed = 1;
      }
      ps[np] = m - 1;
      if (closed && bk->dir != GR_DIR_THIN && short_loop(s->pts, m, track, out)) continue;
      gr_stitch_chain ch = {s->pts, m, closed, bk->kind, bk->dir, ps, pl, np};
      rc = gr_stitch_chain_emit(mach, &ch, out, split);
    }
  }
  free(ps);
  free(pl);
  return rc ? gr_fail(e, GR_EMEM, "out of memory") : GR_OK;
}

/* ---- thin-wall lines across voxel faces ----
 * A thin-wall line has no orientation: the trace of each voxel's template
 * starts at its deepest node, so the pieces two voxels leave at their
 * common face may both end there, or both start there. Joining end to start
 * (as the contours' pieces, whose orientation is the boundary's) would then
 * either leave them apart or, worse, take the far end of a short piece that
 * happens to lie within the tolerance and fold the line back on itself.
 * So thin pieces are joined end to end, either end to either end, nearest
 * pairs first; a piece entered at its end is reversed in place. */

typedef struct thin_pair { double d2; long a, b; } thin_pair; /* ends: 2 piece + (0 start, 1 end) */

static int thin_pair_cmp(const void *x, const void *y) {
  const thin_pair *p = x, *q = y;
  if (p->d2 != q->d2) return p->d2 < q->d2 ? -1 : 1;
  return p->a != q->a ? (p->a < q->a ? -1 : 1) : (p->b > q->b) - (p->b < q->b);
}

static const double *thin_end(const gr_layer *c, size_t b0, long end) {
  const gr_block *bk = &c->b[b0 + (size_t)(end / 2)];
  return c->xy + 2 * (bk->start + (end & 1 ? bk->n - 1 : 0));
}

static int is_thin(const gr_block *bk) { return bk->shape == GR_OPEN && bk->dir == GR_DIR_THIN && bk->n >= 2; }

static void thin_reverse(gr_layer *c, size_t b0, long piece) {
  const gr_block *bk = &c->b[b0 + (size_t)piece];
  double *p = c->xy + 2 * bk->start;
  for (size_t i = 0, k = bk->n - 1; i < k; i++, k--)
    for (int a = 0; a < 2; a++) { double t = p[2 * i + a]; p[2 * i + a] = p[2 * k + a]; p[2 * k + a] = t; }
}

/* Link the thin open pieces among blocks [b0, b0 + n) (next/prev as
 * join_contours keeps them), their ends paired within tol. */
static int join_thin(gr_layer *c, size_t b0, size_t n, double tol, long *next, long *prev) {
  long *part = malloc(2 * n * sizeof *part), *fwd = malloc(n * sizeof *fwd);
  double *ex = malloc(2 * n * 3 * sizeof *ex); /* x, y, end of the thin pieces' ends, sorted by x */
  size_t np = 0, cap = 0, ne = 0;
  thin_pair *pr = NULL;
  int rc = part && fwd && ex ? GR_OK : GR_EMEM;
  for (size_t i = 0; i < n && !rc; i++) {
    part[2 * i] = part[2 * i + 1] = -1;
    fwd[i] = -1; /* not a thin piece, or not yet walked */
    if (!is_thin(&c->b[b0 + i])) continue;
    for (int a = 0; a < 2; a++) {
      const double *p = thin_end(c, b0, 2 * (long)i + a);
      ex[3 * ne] = p[0]; ex[3 * ne + 1] = p[1]; ex[3 * ne + 2] = (double)(2 * (long)i + a);
      ne++;
    }
  }
  if (!rc && ne) qsort(ex, ne, 3 * sizeof *ex, triple_cmp);
  for (size_t u = 0; u < ne && !rc; u++)
    for (size_t w = u + 1; w < ne && ex[3 * w] <= ex[3 * u] + tol; w++) {
      long ea = (long)ex[3 * u + 2], eb = (long)ex[3 * w + 2];
      double dx = ex[3 * u] - ex[3 * w], dy = ex[3 * u + 1] - ex[3 * w + 1], d2 = dx * dx + dy * dy;
      if (ea / 2 == eb / 2 || !(d2 <= tol * tol)) continue;
      if (gr_grow(&pr, &cap, np + 1, sizeof *pr)) { rc = GR_EMEM; break; }
      pr[np++] = (thin_pair){d2, ea < eb ? ea : eb, ea < eb ? eb : ea};
    }
  if (!rc) {
    if (np) qsort(pr, np, sizeof *pr, thin_pair_cmp);
    for (size_t q = 0; q < np; q++)
      if (part[pr[q].a] < 0 && part[pr[q].b] < 0) { part[pr[q].a] = pr[q].b; part[pr[q].b] = pr[q].a; }
    /* walk from the pieces with a free end first, then around what is left (rings) */
    for (int round = 0; round < 2; round++)
      for (size_t i = 0; i < n; i++) {
        if (fwd[i] >= 0 || !is_thin(&c->b[b0 + i])) continue;
        if (round == 0 && part[2 * i] >= 0 && part[2 * i + 1] >= 0) continue;
        long p = (long)i;
        fwd[p] = part[2 * p] < 0 || round == 1; /* enter at a free start, else reversed */
        for (;;) {
          long tail = part[2 * p + (fwd[p] ? 1 : 0)];
          if (tail < 0) break;
          long q = tail / 2;
          if (fwd[q] >= 0) { if (q == (long)i) { next[p] = q; prev[q] = p; } break; }
          fwd[q] = (tail & 1) == 0;
          next[p] = q; prev[q] = p;
          p = q;
        }
      }
    for (size_t i = 0; i < n; i++)
      if (fwd[i] == 0) thin_reverse(c, b0, (long)i);
  }
  free(pr); free(part); free(fwd); free(ex);
  return rc;
}

/* Join open contour pieces whose end meets another's start (within tol)
 * into chains; closed chains become GR_CLOSED loops, each on one laser where
 * one reaches it (stitch.h). Pieces come from s->cont blocks [b0, b1);
 * output appended to `out`. */
static int join_contours(gr_asm_scratch *s, size_t b0, size_t b1, double tol, double track, gr_layer *out,
                         const int *slot_laser, const gr_machine *m, long *split, gr_err *e) {
  gr_layer *c = s->cont;
  size_t n = b1 - b0;
  if (n == 0) return GR_OK;
  if (gr_grow(&s->link, &s->caplink, 3 * n, sizeof *s->link)) return gr_fail(e, GR_EMEM, "out of memory");
  long *next = s->link, *prev = s->link + n, *used = s->link + 2 * n;
  for (size_t i = 0; i < n; i++) next[i] = prev[i] = -1, used[i] = 0;
  if (join_thin(c, b0, n, tol, next, prev)) return gr_fail(e, GR_EMEM, "out of memory");
  /* sort open pieces by start x to find matches in O(n log n) */
  size_t nopen = 0;
  long *idx = malloc((n ? n : 1) * sizeof *idx);
  if (!idx) return gr_fail(e, GR_EMEM, "out of memory");
  for (size_t i = 0; i < n; i++)
    if (c->b[b0 + i].shape == GR_OPEN && c->b[b0 + i].dir != GR_DIR_THIN) idx[nopen++] = (long)i;
  /* insertion into a sorted array by start x (qsort with a context-free
   * comparator needs the coordinates: copy them) */
  double *sx = malloc((nopen ? nopen : 1) * 3 * sizeof *sx);
  if (!sx) { free(idx); return gr_fail(e, GR_EMEM, "out of memory"); }
  for (size_t q = 0; q < nopen; q++) {
    const gr_block *bk = &c->b[b0 + idx[q]];
    sx[3 * q] = c->xy[2 * bk->start];
    sx[3 * q + 1] = c->xy[2 * bk->start + 1];
    sx[3 * q + 2] = (double)idx[q];
  }
  qsort(sx, nopen, 3 * sizeof *sx, triple_cmp);
  for (size_t q = 0; q < nopen; q++) {
    long i = idx[q];
    const gr_block *bk = &c->b[b0 + i];
    double ex = c->xy[2 * (bk->start + bk->n - 1)], ey = c->xy[2 * (bk->start + bk->n - 1) + 1];
    /* binary search the first start with x >= ex - tol */
    size_t lo = 0, hi = nopen;
    while (lo < hi) {
      size_t mid = (lo + hi) / 2;
      if (sx[3 * mid] < ex - tol) lo = mid + 1; else hi = mid;
    }
    long best = -1;
    double bd = tol * tol;
    for (size_t r = lo; r < nopen && sx[3 * r] <= ex + tol; r++) {
      long cand = (long)sx[3 * r + 2];
      if (cand == i || prev[cand] >= 0) continue;
      double dx = sx[3 * r] - ex, dy = sx[3 * r + 1] - ey, d2 = dx * dx + dy * dy;
      if (d2 <= bd) { bd = d2; best = cand; }
    }
    if (best >= 0) { next[i] = best; prev[best] = i; }
  }
  free(sx);
  free(idx);
  return emit_chains(s, b0, n, track, out, slot_laser, m, split, e);
}

/* The voxels of layer g's row (slots in sequence order): template layers
 * translated into place, contours into s->cont (block.laser = slot), hatch
 * segments into s->segs; the lasers assigned into s->vlas. */
static int gather_voxels(gr_job *j, int g, gr_asm_scratch *s, gr_layer *out, gr_err *e) {
  int k = gr_grid_layer_row(&j->grid, g);
  int jl = g - gr_grid_row_first(&j->grid, k);
  const int *vox = j->roworder + (size_t)k * j->rowlen;
  int nslot = j->rowcount[k];
  double a = gr_job_angle(j, g);
  s->nseg = 0;
  gr_layer_clear(s->cont, 0);
  double *lc = s->vtime; /* reuse: contour length per slot, hatch length below */
  double *lh = malloc((size_t)(nslot > 0 ? nslot : 1) * sizeof *lh);
  if (!lh) return gr_fail(e, GR_EMEM, "out of memory");
  gr_fstep_cache_clear(s->fs);
  int rc = GR_OK;
  for (int q = 0; q < nslot && rc == GR_OK; q++) {
    int v = vox[q];
    const gr_tmpl *t = j->cls[j->vcls[v]].t;
    lc[q] = lh[q] = 0;
    s->vcont0[q] = s->cont->nb;
    s->vseg0[q] = s->nseg;
    if (!t || jl < t->j0 || jl >= t->j0 + t->nl) {
      rc = gr_fail(e, GR_EARG, "internal: no template layer %d for voxel %d", jl, v);
      break;
    }
    const gr_tlayer *tl = &t->l[jl - t->j0], *st; /* st: on the true section where a neighbour is graded otherwise */
    if ((rc = gr_fstep_voxel(j, v, jl, s->fs, &st, e))) break;
    if (st) tl = st;
    double o[3];
    gr_grid_origin(&j->grid, v, o);
    out->area += tl->area;
    size_t nb0 = s->cont->nb;
    int mask = gr_voxel_sides(j, v);
    if ((mask && boundary_contours(j, s, tl, mask)) || gr_layer_append(s->cont, mask ? s->fl : tl->paths, o[0], o[1])) {
      rc = gr_fail(e, GR_EMEM, "out of memory");
      break;
    }
    gr_skinring *sr = gr_skinring_new(j, g, v, tl, e); /* more contours along the skin (NULL: none) */
    if (!sr && e->code) { rc = e->code; break; }
    if (sr && (rc = gr_skinring_contours(sr, q, s->cont, e))) { gr_skinring_free(sr); break; }
    for (size_t b = nb0; b < s->cont->nb; b++) {
      s->cont->b[b].laser = q; /* slot, mapped to the laser later */
      lc[q] += gr_block_length(s->cont, &s->cont->b[b]);
    }
    int i, jj, kk;
    gr_grid_ijk(&j->grid, v, &i, &jj, &kk);
    double av = a;
    if (j->o.pattern == GR_PATTERN_ISLAND && ((i + jj) & 1)) av = fmod(a + 90, 360);
    rc = hatch_voxel(j, s, tl, o, av, q, mask, e);
    if (rc == GR_OK) rc = gr_regions_split(j, g, v, sr, &s->segs, &s->nseg, &s->capseg, s->vseg0[q], e);
    gr_skinring_free(sr);
    s->vcont1[q] = s->cont->nb;
    s->vseg1[q] = s->nseg;
    for (size_t r = s->vseg0[q]; r < s->nseg; r++) lh[q] += s->segs[r].s1 - s->segs[r].s0;
  }
  if (rc == GR_OK) rc = gr_lasers_assign(&j->m, &j->grid, j->vlaser, vox, nslot, lc, lh, s->vlas, e);
  free(lh);
  return rc;
}

/* Island mode: per island (voxel) in sequence order, contours and hatches unjoined. */
static int emit_islands(const gr_job *j, gr_asm_scratch *s, int nslot, gr_layer *out, gr_err *e) {
  int cf = j->o.contour_first;
  for (int q = 0; q < nslot; q++) {
    for (int pass = 0; pass < 2; pass++) {
      int contours = (pass == 0) == (cf != 0);
      if (contours) {
        for (size_t b = s->vcont0[q]; b < s->vcont1[q]; b++) {
          const gr_block *bk = &s->cont->b[b];
          const double *bp = s->cont->xy + 2 * bk->start;
          if (bk->shape == GR_CLOSED && short_loop(bp, bk->n, j->o.track, out)) continue;
          if (gr_layer_add(out, bk->shape, bk->kind, s->vlas[q], bk->dir, s->cont->xy + 2 * bk->start, bk->n))
            return gr_fail(e, GR_EMEM, "out of memory");
        }
      } else {
        long lastline = LONG_MIN;
        int flip = 0;
        for (size_t r = s->vseg0[q]; r < s->vseg1[q]; r++) {
          const seg *sg = &s->segs[r];
          if (sg->line != lastline) { flip = !flip; lastline = sg->line; }
          int rev = j->o.alternate && flip;
          if (gr_layer_add_segment_r(out, GR_HATCH, sg->region, s->vlas[q], rev ? sg->x1 : sg->x0, rev ? sg->y1 : sg->y0,
                                   rev ? sg->x0 : sg->x1, rev ? sg->y0 : sg->y1))
            return gr_fail(e, GR_EMEM, "out of memory");
        }
      }
    }
  }
  return GR_OK;
}

/* Continuous mode: hatches joined along their lines across voxels, into
 * `hat` (vectors shorter than the minimum length dropped and counted). */
static int join_hatches(gr_job *j, gr_asm_scratch *s, gr_layer *hat, gr_err *e) {
  if (sort_segs(s, e)) return e->code;
  size_t w = 0;
  double tol = 1e-7;
  for (size_t r = 0; r < s->nseg; r++) {
    if (w > 0 && s->segs[w - 1].laser == s->segs[r].laser && s->segs[w - 1].line == s->segs[r].line &&
        s->segs[w - 1].region == s->segs[r].region && s->segs[r].s0 <= s->segs[w - 1].s1 + tol) {
      if (s->segs[r].s1 > s->segs[w - 1].s1) {
        s->segs[w - 1].s1 = s->segs[r].s1;
        s->segs[w - 1].x1 = s->segs[r].x1;
        s->segs[w - 1].y1 = s->segs[r].y1;
      }
    } else {
      s->segs[w++] = s->segs[r];
    }
  }
  s->nseg = w;
  if (gr_stitch_hatches(&j->m, s->segs, s->nseg)) return gr_fail(e, GR_EMEM, "out of memory");
  long lastline = LONG_MIN;
  int flip = 0, lastlaser = -1;
  for (size_t r = 0; r < s->nseg; r++) {
    const seg *sg = &s->segs[r];
    if (sg->s1 - sg->s0 < j->o.min_length) { __atomic_fetch_add(&j->st_dropped, 1, __ATOMIC_RELAXED); continue; }
    if (sg->laser != lastlaser) { flip = 0; lastline = LONG_MIN; lastlaser = sg->laser; }
    if (sg->line != lastline) { flip = !flip; lastline = sg->line; }
    int rev = j->o.alternate && !flip;
    if (gr_layer_add_segment_r(hat, GR_HATCH, sg->region, sg->laser, rev ? sg->x1 : sg->x0, rev ? sg->y1 : sg->y0,
                             rev ? sg->x0 : sg->x1, rev ? sg->y0 : sg->y1))
      return gr_fail(e, GR_EMEM, "out of memory");
  }
  return GR_OK;
}

/* Continuous mode: hatches and contours joined across voxels; per laser,
 * contours then hatches (or the reverse). */
static int emit_continuous(gr_job *j, gr_asm_scratch *s, gr_layer *out, gr_err *e) {
  int cf = j->o.contour_first;
  gr_layer *hat = gr_layer_new(0);
  if (!hat) return gr_fail(e, GR_EMEM, "out of memory");
  int rc = join_hatches(j, s, hat, e);
  if (rc) { gr_layer_free(hat); return rc; }
  gr_layer *con = gr_layer_new(0);
  if (!con) { gr_layer_free(hat); return gr_fail(e, GR_EMEM, "out of memory"); }
  long split = 0;
  rc = join_contours(s, 0, s->cont->nb, j->o.hatch / 4, j->o.track, con, s->vlas, &j->m, &split, e);
  out->short_loops += con->short_loops;
  out->short_length += con->short_length;
  if (split) __atomic_fetch_add(&j->st_split, split, __ATOMIC_RELAXED);
  for (int la = 0; la < j->m.n && rc == GR_OK; la++) {
    for (int pass = 0; pass < 2 && rc == GR_OK; pass++) {
      const gr_layer *src = ((pass == 0) == (cf != 0)) ? con : hat;
      for (size_t b = 0; b < src->nb; b++) {
        const gr_block *bk = &src->b[b];
        if (bk->laser != la) continue;
        if (gr_layer_add(out, bk->shape, bk->kind, la, bk->dir, src->xy + 2 * bk->start, bk->n)) {
          rc = gr_fail(e, GR_EMEM, "out of memory");
          break;
        }
        out->b[out->nb - 1].region = bk->region;
      }
    }
  }
  gr_layer_free(hat);
  gr_layer_free(con);
  return rc;
}

int gr_asm_layer(gr_job *j, int g, gr_asm_scratch *s, gr_layer *out, gr_err *e) {
  gr_layer_clear(out, j->o.origin[2] + g * j->o.layer);
  int rc = gather_voxels(j, g, s, out, e);
  if (rc) return rc;
  out->thin_walls = s->cont->thin_walls;
  for (size_t r = 0; r < s->nseg; r++) s->segs[r].laser = s->vlas[s->segs[r].voxel];
  rc = j->o.pattern == GR_PATTERN_ISLAND ? emit_islands(j, s, j->rowcount[gr_grid_layer_row(&j->grid, g)], out, e)
                                         : emit_continuous(j, s, out, e);
  if (rc == GR_OK) rc = gr_facing_contours(j, g, out, e);
  if (rc == GR_OK) gr_regions_tag_thin(j, out);
  return rc;
}
