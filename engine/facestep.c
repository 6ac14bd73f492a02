/* facestep.c: the voxel-owned section of a window across voxel faces, see
 * facestep.h.
 *
 * The window is tiled by nine boxes (the centre voxel, its four side and four
 * corner neighbours, each cut to the window). The section's boundary is
 *  - each box's section boundary inside the box (its rings clipped to it), and
 *  - on the lines that carry the boxes' sides, the parts where the solid is
 *    on one side only: every box contributes its sides' solid intervals,
 *    oriented counter-clockwise around the box; on a face shared by two boxes
 *    the two directions cancel where both are solid, so what is left is the
 *    step (and on the window's border, its closure).
 * The pieces end exactly on the lines (snapped), the line intervals start
 * and end at those very coordinates, so they chain into closed rings by
 * exact matching of end points. */
#include "facestep.h"
#include "expr.h"
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <stdint.h>
#include "clip.h"
#include "hatch.h"
#include "regions.h"

/* Piece end points within this of a box side lie on it (mm). */
#define ON_SIDE 1e-9
/* A voxel's section continued past a side and its neighbour's own section
 * whose crossings of the face and of lines parallel to it agree within this
 * (mm) are taken to agree there: the template's continuation of the voxel's
 * own grading stands. */
#define FACE_TOL 2e-4
/* The window's border is drawn this far inside the templates' (mm). */
#define INSET 1e-6
/* Chain end points this close are the same point (mm). */
#define JOIN 1e-9

typedef struct fs_iv {
  int line;    /* 0..3: x = X[0][line]; 4..7: y = X[1][line - 4] */
  double a, b; /* a < b, along the line */
  int sgn;     /* +1: runs from a to b, -1: from b to a */
} fs_iv;

typedef struct fs_work {
  double X[2][4];    /* per axis x, y: -m, 0, L, L + m (the outer two INSET inside) */
  gr_rings *tr;      /* one box's rings, translated */
  gr_layer *pc;      /* one box's clipped pieces */
  gr_layer *ed;      /* the boundary's edges (open polylines) */
  fs_iv *iv;
  size_t niv, capiv;
  double *bp;        /* breakpoints, scratch */
  size_t capbp;
  double *buf;       /* clip scratch */
  size_t capbuf;
} fs_work;

static int dbl_cmp(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

static int push_iv(fs_work *w, int line, double a, double b, int sgn) {
  if (gr_grow(&w->iv, &w->capiv, w->niv + 1, sizeof *w->iv)) return GR_EMEM;
  w->iv[w->niv++] = (fs_iv){line, a, b, sgn};
  return GR_OK;
}

/* Side s (0 bottom, 1 right, 2 top, 3 left: counter-clockwise) of the box
 * lo..hi: its line, fixed coordinate, along-axis range and direction. */
static void box_side(const fs_work *w, int bi, int bj, int s, int *line, double *fix, double *a, double *b,
                     int *sgn) {
  int vert = s & 1, hiside = s == 1 || s == 2;
  int k = vert ? bi + hiside : bj + hiside;  /* index into X */
  *line = vert ? k : 4 + k;
  *fix = vert ? w->X[0][k] : w->X[1][k];
  *a = vert ? w->X[1][bj] : w->X[0][bi];
  *b = vert ? w->X[1][bj + 1] : w->X[0][bi + 1];
  *sgn = s < 2 ? 1 : -1;
}

/* Snap the end points of box (bi, bj)'s open pieces onto the sides they lie
 * on, then add each side's solid intervals (split at those end points). */
static int box_sides(fs_work *w, int bi, int bj) {
  for (int s = 0; s < 4; s++) {
    int line, sgn, vert = s & 1;
    double fix, a, b;
    box_side(w, bi, bj, s, &line, &fix, &a, &b, &sgn);
    size_t nb = 0;
    if (gr_grow(&w->bp, &w->capbp, 2 * w->pc->nb + 2, sizeof *w->bp)) return GR_EMEM;
    w->bp[nb++] = a;
    w->bp[nb++] = b;
    for (size_t k = 0; k < w->pc->nb; k++) {
      const gr_block *bk = &w->pc->b[k];
      if (bk->shape != GR_OPEN) continue;
      for (int end = 0; end < 2; end++) {
        double *p = w->pc->xy + 2 * (bk->start + (end ? bk->n - 1 : 0));
        if (fabs(p[vert ? 0 : 1] - fix) > ON_SIDE) continue;
        p[vert ? 0 : 1] = fix;
        double t = p[vert ? 1 : 0];
        if (t > a && t < b) w->bp[nb++] = t;
      }
    }
    if (nb > 1) qsort(w->bp, nb, sizeof *w->bp, dbl_cmp);
    for (size_t k = 0; k + 1 < nb; k++) {
      double p = w->bp[k], q = w->bp[k + 1], mid = 0.5 * (p + q);
      if (!(q > p)) continue;
      int in = vert ? gr_rings_contains(w->tr, fix, mid) : gr_rings_contains(w->tr, mid, fix);
      if (in && push_iv(w, line, p, q, sgn)) return GR_EMEM;
    }
  }
  return GR_OK;
}

/* Box (bi, bj) of the window (0..2 each) with rings r in its own voxel's
 * coordinates, moved by (dx, dy): closed rings inside it go to out, open
 * pieces to w->ed, side intervals to w->iv. */
static int add_box(fs_work *w, int bi, int bj, const gr_rings *r, double dx, double dy, gr_rings *out) {
  double lo[2] = {w->X[0][bi], w->X[1][bj]}, hi[2] = {w->X[0][bi + 1], w->X[1][bj + 1]};
  gr_rings_clear(w->tr);
  gr_layer_clear(w->pc, 0);
  if (gr_rings_append(w->tr, r, dx, dy)) return GR_EMEM;
  for (size_t i = 0; i < w->tr->nrings; i++)
    if (gr_clip_poly(gr_ring_xy(w->tr, i), gr_ring_len(w->tr, i), 1, GR_CONTOUR, 1, lo, hi, w->pc, &w->buf,
                     &w->capbuf))
      return GR_EMEM;
  if (box_sides(w, bi, bj)) return GR_EMEM;
  for (size_t k = 0; k < w->pc->nb; k++) {
    const gr_block *bk = &w->pc->b[k];
    const double *p = w->pc->xy + 2 * bk->start;
    if (bk->shape == GR_CLOSED) {
      if (bk->n > 3 && gr_rings_add(out, p, bk->n - 1)) return GR_EMEM;
    } else if (gr_layer_add(w->ed, GR_OPEN, GR_CONTOUR, 0, 2, p, bk->n)) {
      return GR_EMEM;
    }
  }
  return GR_OK;
}

/* Net direction of each line's elementary intervals: the face segments. */
static int line_edges(fs_work *w) {
  for (int line = 0; line < 8; line++) {
    size_t nb = 0;
    if (gr_grow(&w->bp, &w->capbp, 2 * w->niv + 1, sizeof *w->bp)) return GR_EMEM;
    for (size_t k = 0; k < w->niv; k++)
      if (w->iv[k].line == line) { w->bp[nb++] = w->iv[k].a; w->bp[nb++] = w->iv[k].b; }
    if (nb > 1) qsort(w->bp, nb, sizeof *w->bp, dbl_cmp);
    double fix = w->X[line >> 2][line & 3];
    for (size_t k = 0; k + 1 < nb; k++) {
      double p = w->bp[k], q = w->bp[k + 1], mid = 0.5 * (p + q);
      if (!(q > p)) continue;
      int net = 0;
      for (size_t r = 0; r < w->niv; r++)
        if (w->iv[r].line == line && w->iv[r].a < mid && w->iv[r].b > mid) net += w->iv[r].sgn;
      if (net == 0) continue;
      double s = net > 0 ? p : q, t = net > 0 ? q : p;
      double seg[4] = {line < 4 ? fix : s, line < 4 ? s : fix, line < 4 ? fix : t, line < 4 ? t : fix};
      if (gr_layer_add(w->ed, GR_OPEN, GR_CONTOUR, 0, 2, seg, 2)) return GR_EMEM;
    }
  }
  return GR_OK;
}

/* Chain w->ed's edges end to start into closed rings (out). GR_EARG when an
 * edge's end meets no start. */
static int chain(fs_work *w, gr_rings *out, gr_err *e) {
  const gr_layer *ed = w->ed;
  size_t n = ed->nb;
  char *used = calloc(n ? n : 1, 1);
  if (!used) return gr_fail(e, GR_EMEM, "out of memory");
  int rc = GR_OK;
  for (size_t i = 0; i < n && rc == GR_OK; i++) {
    if (used[i]) continue;
    const double *s0 = ed->xy + 2 * ed->b[i].start;
    size_t cur = i;
    for (;;) {
      const gr_block *bk = &ed->b[cur];
      used[cur] = 1;
      for (size_t k = 0; k + 1 < bk->n && rc == GR_OK; k++)
        if (gr_rings_point(out, ed->xy[2 * (bk->start + k)], ed->xy[2 * (bk->start + k) + 1])) rc = GR_EMEM;
      if (rc) break;
      const double *end = ed->xy + 2 * (bk->start + bk->n - 1);
      if (fabs(end[0] - s0[0]) <= JOIN && fabs(end[1] - s0[1]) <= JOIN) break;
      size_t best = n;
      double bd = JOIN * JOIN * 2;
      for (size_t k = 0; k < n; k++) {
        if (used[k]) continue;
        const double *q = ed->xy + 2 * ed->b[k].start;
        double dx = q[0] - end[0], dy = q[1] - end[1];
        if (dx * dx + dy * dy <= bd) { bd = dx * dx + dy * dy; best = k; }
      }
      if (best == n) { rc = gr_fail(e, GR_EARG, "face step: open boundary at (%g, %g)", end[0], end[1]); break; }
      cur = best;
    }
    if (rc == GR_OK && gr_rings_close(out)) rc = GR_EMEM;
  }
  free(used);
  if (rc == GR_EMEM) return gr_fail(e, GR_EMEM, "out of memory");
  return rc;
}

int gr_fstep_section(const double L[2], double m, const gr_rings *const nb[9], gr_rings *out, gr_err *e) {
  fs_work w;
  memset(&w, 0, sizeof w);
  /* the templates' sections are closed along their windows' borders: stay
   * just inside, so that no box side runs along a section edge */
  for (int a = 0; a < 2; a++) {
    w.X[a][0] = -m + INSET;
    w.X[a][1] = 0;
    w.X[a][2] = L[a];
    w.X[a][3] = L[a] + m - INSET;
  }
  gr_rings_clear(out);
  w.tr = gr_rings_new();
  w.pc = gr_layer_new(0);
  w.ed = gr_layer_new(0);
  int rc = (w.tr && w.pc && w.ed) ? GR_OK : GR_EMEM;
  for (int bj = 0; bj < 3 && rc == GR_OK; bj++)
    for (int bi = 0; bi < 3 && rc == GR_OK; bi++) {
      const gr_rings *r = nb[3 * bj + bi];
      int own = r != NULL;
      rc = add_box(&w, bi, bj, own ? r : nb[4], own ? (bi - 1) * L[0] : 0, own ? (bj - 1) * L[1] : 0, out);
    }
  if (rc == GR_OK) rc = line_edges(&w);
  if (rc == GR_OK) rc = chain(&w, out, e);
  else gr_fail(e, GR_EMEM, "out of memory");
  if (rc) gr_rings_clear(out);
  gr_rings_free(w.tr);
  gr_layer_free(w.pc);
  gr_layer_free(w.ed);
  free(w.iv);
  free(w.bp);
  free(w.buf);
  return rc;
}

/* The template layer of voxel v (local layer jl of its row), NULL when v has
 * no class or template. */
static const gr_tlayer *voxel_layer(const gr_job *j, int v, int jl) {
  if (j->vcls[v] < 0) return NULL;
  const gr_tmpl *t = j->cls[j->vcls[v]].t;
  if (!t || jl < t->j0 || jl >= t->j0 + t->nl) return NULL;
  return &t->l[jl - t->j0];
}

/* Where ring set r crosses the lines x = pos[q] (vert) or y = pos[q], q <
 * NQ, along them, within [0, L] (L: the voxel's length along the lines):
 * one pass over the edges, each line's crossings sorted into c[q] (grown),
 * counts into n[q]; -1 out of memory, else 0. */
enum { NQ = 4 };
static int face_crossings(const gr_rings *r, int vert, const double pos[NQ], double L, double *c[NQ],
                          size_t cap[NQ], long n[NQ]) {
  for (int q = 0; q < NQ; q++) n[q] = 0;
  for (size_t i = 0; i < r->nrings; i++) {
    const double *p = gr_ring_xy(r, i);
    size_t m = gr_ring_len(r, i);
    for (size_t a = 0; a < m; a++) {
      const double *P = p + 2 * a, *Q = p + 2 * ((a + 1) % m);
      double pa = vert ? P[0] : P[1], qa = vert ? Q[0] : Q[1];
      for (int q = 0; q < NQ; q++) {
        if ((pa > pos[q]) == (qa > pos[q])) continue;
        double pl = vert ? P[1] : P[0], ql = vert ? Q[1] : Q[0], t = pl + (pos[q] - pa) * (ql - pl) / (qa - pa);
        if (t < 0 || t > L) continue;
        if (gr_grow(&c[q], &cap[q], (size_t)n[q] + 1, sizeof *c[q])) return -1;
        c[q][n[q]++] = t;
      }
    }
  }
  for (int q = 0; q < NQ; q++)
    if (n[q] > 1) qsort(c[q], (size_t)n[q], sizeof *c[q], dbl_cmp);
  return 0;
}

/* A template layer's crossings of the face-check lines, for each side
 * (0 x = 0, 1 x = Lx, 2 y = 0, 3 y = Ly) and role: role 0, the section
 * continued past the side, lines s = 0, h/3, 2h/3, h beyond it; role 1, the
 * section inside its voxel, the same distances in from the side (h: the hatch
 * offset, the farthest the contours and hatch region look across a face).
 * Counts n, starts at, the crossings sorted along each line in c. One block. */
typedef struct gr_fxing {
  long n[2][4][NQ];
  size_t at[2][4][NQ];
  double c[];
} gr_fxing;

/* The lines of side `side`, role `role`, and the cell's lengths across and along them. */
static void fx_lines(int side, int role, const double cell[2], double h, double pos[NQ], double *L) {
  int vert = side < 2;
  double Lc = vert ? cell[0] : cell[1];
  *L = vert ? cell[1] : cell[0];
  for (int q = 0; q < NQ; q++) {
    double s = q * h / 3;
    pos[q] = role == 0 ? ((side & 1) ? Lc + s : -s) : ((side & 1) ? s : Lc - s);
  }
}

static gr_fxing *fx_make(const gr_rings *r, const double cell[2], double h) {
  double *c[2][4][NQ] = {{{NULL}}};
  size_t cap[2][4][NQ] = {{{0}}}, tot = 0;
  long n[2][4][NQ];
  int bad = 0;
  for (int role = 0; role < 2 && !bad; role++)
    for (int side = 0; side < 4 && !bad; side++) {
      double pos[NQ], L;
      fx_lines(side, role, cell, h, pos, &L);
      bad = face_crossings(r, side < 2, pos, L, c[role][side], cap[role][side], n[role][side]);
      for (int q = 0; q < NQ && !bad; q++) tot += (size_t)n[role][side][q];
    }
  gr_fxing *f = bad ? NULL : malloc(sizeof *f + tot * sizeof *f->c);
  if (f) {
    size_t at = 0;
    for (int role = 0; role < 2; role++)
      for (int side = 0; side < 4; side++)
        for (int q = 0; q < NQ; q++) {
          f->n[role][side][q] = n[role][side][q];
          f->at[role][side][q] = at;
          if (n[role][side][q]) memcpy(f->c + at, c[role][side][q], (size_t)n[role][side][q] * sizeof *f->c);
          at += (size_t)n[role][side][q];
        }
  }
  for (int role = 0; role < 2; role++)
    for (int side = 0; side < 4; side++)
      for (int q = 0; q < NQ; q++) free(c[role][side][q]);
  return f;
}

/* tl's crossings, made on first use. Template layers are shared by the
 * assembly threads: the first to finish installs its block, a loser frees
 * its own. NULL when out of memory. */
static const gr_fxing *fx_of(const gr_tlayer *tl, const double cell[2], double h) {
  _Atomic(gr_fxing *) *slot = (_Atomic(gr_fxing *) *)&tl->fx; /* a cache in a shared, read-only layer */
  gr_fxing *f = atomic_load_explicit(slot, memory_order_acquire);
  if (f) return f;
  gr_fxing *mine = fx_make(tl->section, cell, h), *none = NULL;
  if (!mine) return NULL;
  if (atomic_compare_exchange_strong_explicit(slot, &none, mine, memory_order_acq_rel, memory_order_acquire))
    return mine;
  free(mine);
  return none;
}

/* 1 if layer a's section continued past side `side` and its side
 * neighbour b's own section cross the shared face, or the lines h/3, 2h/3
 * and h into the neighbour, at different places (beyond FACE_TOL); 0 if
 * not, -1 out of memory. */
static int face_differs(const gr_tlayer *a, const gr_tlayer *b, int side, const double cell[2], double h) {
  const gr_fxing *fa = fx_of(a, cell, h), *fb = fx_of(b, cell, h);
  if (!fa || !fb) return -1;
  for (int q = 0; q < NQ; q++) {
    long na = fa->n[0][side][q];
    if (na != fb->n[1][side][q]) return 1;
    const double *ca = fa->c + fa->at[0][side][q], *cb = fb->c + fb->at[1][side][q];
    for (long k = 0; k < na; k++)
      if (fabs(ca[k] - cb[k]) > FACE_TOL) return 1;
  }
  return 0;
}

/* 1 when voxels v and n cannot step at their shared face: the same spec,
 * neither cut by the domain, and a thickness that reads neither u nor v
 * (x, y, z are global, w is the same in a row: the solid is continuous
 * across the face). Such neighbours are not checked. */
static int continuous_face(const gr_job *j, int v, int n) {
  int s = j->vspec[v];
  if (s < 0 || j->vspec[n] != s || j->vstate[v] == 2 || j->vstate[n] == 2) return 0;
  if (j->specs[s].target) return 1; /* a field of x, y, z */
  const gr_expr *t = j->texpr[s], *in = j->iexpr[s];
  return !gr_expr_uses(t, 3) && !gr_expr_uses(t, 4) && !(in && (gr_expr_uses(in, 3) || gr_expr_uses(in, 4)));
}

/* A voxel's neighbourhood on one layer: the nine template layers around it
 * (NULL: no neighbour) and which of its four side faces are continuous
 * (continuous_face). The stepped layer is a function of it alone. */
typedef struct fs_key {
  const gr_tlayer *nb[9];
  int cont;
} fs_key;

typedef struct fs_entry {
  fs_key k;
  gr_tlayer *tl; /* the layer on the true section; NULL: the template's stands */
  int used;
} fs_entry;

struct gr_fstep_cache {
  fs_entry *e;
  size_t n, cap; /* entries held, slots (a power of two, at most half full) */
};

gr_fstep_cache *gr_fstep_cache_new(void) { return calloc(1, sizeof(gr_fstep_cache)); }

void gr_fstep_cache_clear(gr_fstep_cache *c) {
  if (!c) return;
  for (size_t k = 0; k < c->cap; k++)
    if (c->e[k].used && c->e[k].tl) { gr_fstep_free(c->e[k].tl); free(c->e[k].tl); }
  if (c->e) memset(c->e, 0, c->cap * sizeof *c->e);
  c->n = 0;
}

void gr_fstep_cache_free(gr_fstep_cache *c) {
  if (!c) return;
  gr_fstep_cache_clear(c);
  free(c->e);
  free(c);
}

static size_t key_hash(const fs_key *k) {
  uint64_t h = 1469598103934665603ull ^ (uint64_t)k->cont;
  for (int q = 0; q < 9; q++) h = (h ^ (uint64_t)(uintptr_t)k->nb[q]) * 1099511628211ull;
  return (size_t)(h ^ (h >> 29));
}

/* The slot of key k: its entry, or the free slot where it goes. */
static fs_entry *cache_slot(gr_fstep_cache *c, const fs_key *k) {
  size_t m = c->cap - 1;
  for (size_t i = key_hash(k) & m;; i = (i + 1) & m)
    if (!c->e[i].used || (c->e[i].k.cont == k->cont && !memcmp(c->e[i].k.nb, k->nb, sizeof k->nb))) return &c->e[i];
}

/* Room for one more entry (doubling and rehashing at half full); -1 out of memory. */
static int cache_room(gr_fstep_cache *c) {
  if (2 * (c->n + 1) <= c->cap) return 0;
  size_t cap = c->cap ? 2 * c->cap : 64;
  gr_fstep_cache old = *c;
  if (!(c->e = calloc(cap, sizeof *c->e))) { c->e = old.e; return -1; }
  c->cap = cap;
  for (size_t k = 0; k < old.cap; k++)
    if (old.e[k].used) *cache_slot(c, &old.e[k].k) = old.e[k];
  free(old.e);
  return 0;
}

/* Voxel v's neighbourhood on row layer jl into k, its own layer into *own
 * (NULL: no template layer). GR_EARG when a neighbour's template has lost
 * its section. */
static int neighbourhood(const gr_job *j, int v, int jl, fs_key *k, const gr_tlayer **own, gr_err *e) {
  int i, jj, kk, nx = j->o.n[0], ny = j->o.n[1];
  gr_grid_ijk(&j->grid, v, &i, &jj, &kk);
  *own = voxel_layer(j, v, jl);
  memset(k, 0, sizeof *k);
  if (!*own) return GR_OK;
  for (int dj = -1; dj <= 1; dj++)
    for (int di = -1; di <= 1; di++) {
      const gr_tlayer *tl = NULL;
      if (i + di >= 0 && i + di < nx && jj + dj >= 0 && jj + dj < ny) tl = voxel_layer(j, v + di + dj * nx, jl);
      if (tl && !tl->section) /* templates keep their sections (build.c) */
        return gr_fail(e, GR_EARG, "internal: the template of voxel %d has no section on row layer %d", v + di + dj * nx, jl);
      k->nb[3 * (dj + 1) + di + 1] = tl;
      int side = di < 0 ? 0 : di > 0 ? 1 : dj < 0 ? 2 : 3;
      if (tl && (di == 0) != (dj == 0) && continuous_face(j, v, v + di + dj * nx)) k->cont |= 1 << side;
    }
  return GR_OK;
}

/* The stepped layer of neighbourhood k (own: k.nb[4]) into *out (NULL: not
 * needed, or degenerate: the template's layer stands). */
static int stepped_layer(const gr_job *j, const fs_key *k, gr_tlayer **out, gr_err *e) {
  const gr_tlayer *own = k->nb[4];
  int differ = 0, nc = j->o.contours;
  double h = j->o.beam_offset + (nc > 1 ? nc - 1 : 0) * j->o.hatch + gr_hatch_defaults().gap;
  static const int side_of[4] = {2, 0, 1, 3}, at[4] = {1, 3, 5, 7}; /* nb index -> side */
  for (int q = 0; q < 4 && !differ; q++) {
    const gr_tlayer *tl = k->nb[at[q]];
    int side = side_of[q];
    if (!tl || (k->cont >> side & 1)) continue;
    /* both ways: the two voxels must agree on whether the face steps */
    int r = face_differs(own, tl, side, j->o.cell, h);
    if (r == 0) r = face_differs(tl, own, side ^ 1, j->o.cell, h);
    if (r < 0) return gr_fail(e, GR_EMEM, "out of memory");
    differ = r;
  }
  *out = NULL;
  if (!differ) return GR_OK;
  gr_tlayer *st = calloc(1, sizeof *st);
  if (!st || !(st->section = gr_rings_new())) { free(st); return gr_fail(e, GR_EMEM, "out of memory"); }
  /* its box (just inside the neighbours' windows: gr_fstep_section) is
   * cut as a window is: the sides are no walls, the section goes on */
  double m = gr_job_window(j);
  st->cut[0] = st->cut[1] = -m + INSET;
  st->cut[2] = j->o.cell[0] + m - INSET;
  st->cut[3] = j->o.cell[1] + m - INSET;
  const gr_rings *nb[9];
  for (int q = 0; q < 9; q++) nb[q] = k->nb[q] ? k->nb[q]->section : NULL;
  int rc = gr_fstep_section(j->o.cell, m, nb, st->section, e);
  if (rc == GR_EARG) { /* degenerate: keep the template's layer */
    gr_err_clear(e);
    gr_fstep_free(st);
    free(st);
    return GR_OK;
  }
  if (rc == GR_OK) {
    st->area = own->area;
    st->q[0] = st->q[1] = st->q[2] = NAN;
    rc = gr_tmpl_paths(&j->o, st, 1, e);
  }
  if (rc == GR_OK) *out = st;
  else { gr_fstep_free(st); free(st); }
  return rc;
}

int gr_fstep_voxel(const gr_job *j, int v, int jl, gr_fstep_cache *c, const gr_tlayer **out, gr_err *e) {
  *out = NULL;
  fs_key k;
  const gr_tlayer *own;
  int rc = neighbourhood(j, v, jl, &k, &own, e);
  if (rc || !own) return rc;
  if (cache_room(c)) return gr_fail(e, GR_EMEM, "out of memory");
  fs_entry *en = cache_slot(c, &k);
  if (!en->used) {
    gr_tlayer *st;
    if ((rc = stepped_layer(j, &k, &st, e))) return rc;
    *en = (fs_entry){k, st, 1};
    c->n++;
  }
  *out = en->tl;
  return GR_OK;
}

void gr_fstep_free(gr_tlayer *tl) {
  gr_rings_free(tl->section);
  gr_rings_free(tl->region);
  gr_layer_free(tl->paths);
  gr_layer_free(tl->faces);
  free(atomic_load(&tl->fx));
  memset(tl, 0, sizeof *tl);
}
