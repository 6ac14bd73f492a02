/* paths.h: the 2-D data of one layer.
 *  - gr_rings: closed polygons (section boundaries, contour loops) with
 *    orientation and nesting: outer rings counter-clockwise, holes clockwise.
 *  - gr_layer: the scan vectors of one layer, as blocks of points tagged with
 *    vector kind, shape and laser; the unit of CLI output and of pictures. */
#ifndef GR_PATHS_H
#define GR_PATHS_H
#include "common.h"

/* Ring r has the points xy[2*start[r] .. 2*start[r+1]), mm. The closing
 * segment from the last point back to the first is implicit (the first point
 * is NOT repeated). */
typedef struct gr_rings {
  double *xy;
  size_t npts, cappts;   /* points, capacity (points) */
  size_t *start;         /* nrings + 1 offsets (start[0] = 0) */
  size_t nrings, caprings;
  int *parent;           /* enclosing ring or -1; filled by gr_rings_nest */
} gr_rings;

gr_rings *gr_rings_new(void);
void gr_rings_free(gr_rings *r); /* NULL is fine */
void gr_rings_clear(gr_rings *r);
/* Append one ring of n points (copied). */
int gr_rings_add(gr_rings *r, const double *xy, size_t n);
/* Build a ring point by point: gr_rings_point ... gr_rings_close (inline:
 * the chord passes rebuild their rings a point at a time). */
static inline int gr_rings_point(gr_rings *r, double x, double y) {
  if (r->npts >= r->cappts && gr_grow(&r->xy, &r->cappts, r->npts + 1, 2 * sizeof(double))) return GR_EMEM;
  r->xy[2 * r->npts] = x;
  r->xy[2 * r->npts + 1] = y;
  r->npts++;
  return GR_OK;
}
int gr_rings_close(gr_rings *r); /* ends the ring begun by the points since the last close */
static inline size_t gr_ring_len(const gr_rings *r, size_t i) { return r->start[i + 1] - r->start[i]; }
static inline const double *gr_ring_xy(const gr_rings *r, size_t i) { return r->xy + 2 * r->start[i]; }
/* The index after / before k on a ring of n points (k < n): no division in
 * loops over every point of a section. */
static inline size_t gr_ring_next(size_t k, size_t n) { return k + 1 < n ? k + 1 : 0; }
static inline size_t gr_ring_prev(size_t k, size_t n) { return k ? k - 1 : n - 1; }
/* (k + d) modulo n for k < n and a small d >= 0, without a division. */
static inline size_t gr_ring_at(size_t k, size_t d, size_t n) {
  size_t x = k + d;
  while (x >= n) x -= n;
  return x;
}
double gr_ring_area(const gr_rings *r, size_t i);   /* signed, CCW > 0, mm^2 */
double gr_ring_length(const gr_rings *r, size_t i); /* perimeter, mm */
/* Sum of signed areas: with correct orientation, the area of the region. */
double gr_rings_area(const gr_rings *r);
/* nxt[k] (r->npts entries): the point after k on its ring (global indices). */
void gr_rings_successors(const gr_rings *r, size_t *nxt);
/* Distance from point p to segment a-b (mm). */
double gr_seg_dist(const double *p, const double *a, const double *b);
/* Its square (no root: for comparisons with a squared bound). */
static inline double gr_seg_dist2(const double *p, const double *a, const double *b) {
  double ex = b[0] - a[0], ey = b[1] - a[1], L2 = ex * ex + ey * ey;
  double t = L2 > 0 ? ((p[0] - a[0]) * ex + (p[1] - a[1]) * ey) / L2 : 0;
  t = t < 0 ? 0 : t > 1 ? 1 : t;
  double dx = a[0] + t * ex - p[0], dy = a[1] + t * ey - p[1];
  return dx * dx + dy * dy;
}
/* Bounding box of ring i: x0 y0 x1 y1 into b (mm). */
void gr_ring_box(const gr_rings *r, size_t i, double b[4]);
/* Even-odd test of ring i alone (1 inside). */
int gr_ring_contains(const gr_rings *r, size_t i, double x, double y);
/* Even-odd point-in-region test (1 inside). */
int gr_rings_contains(const gr_rings *r, double x, double y);
/* Compute parent[] (the smallest ring containing each ring) and reorient:
 * rings at even depth CCW (outer), odd depth CW (holes). Rings must not cross. */
int gr_rings_nest(gr_rings *r, gr_err *e);
void gr_rings_translate(gr_rings *r, double dx, double dy);
int gr_rings_copy(gr_rings *dst, const gr_rings *src); /* dst is cleared first */
int gr_rings_append(gr_rings *dst, const gr_rings *src, double dx, double dy);
/* Drop points whose removal moves no ring by more than tol (mm): Douglas-
 * Peucker on each ring, in place; every ring keeps at least 3 points and its
 * place (nesting stays valid). */
int gr_rings_simplify(gr_rings *r, double tol);

/* ---- scan vectors ---- */
enum gr_kind { GR_CONTOUR = 0, GR_HATCH = 1, GR_EDGE = 2, GR_NKINDS = 3 };
enum gr_shape {
  GR_CLOSED = 0,   /* closed polyline; the first point IS repeated at the end */
  GR_OPEN = 1,     /* open polyline (a joined zigzag, a thin-wall centre line) */
  GR_SEGMENTS = 2  /* independent hatch vectors: n is even, pairs of points */
};
#define GR_DIR_THIN 3 /* dir of thin-wall scans (GR_OPEN, GR_CONTOUR), see hatch.h */
typedef struct gr_block {
  int shape;       /* enum gr_shape */
  int kind;        /* enum gr_kind */
  int laser;       /* 0-based laser index */
  int dir;         /* CLI direction: 1 CCW outer, 0 CW hole, 2 open (polylines),
                      GR_DIR_THIN: an open thin-wall centre line (written as 2) */
  size_t start, n; /* points xy[2*start .. 2*(start+n)) */
  int region;      /* enum gr_region (regions.h); 0 = the lattice core */
} gr_block;
/* Regions with their own build styles (regions.h). The CLI id of a block is
 * region * GR_REGION_IDS + laser * 3 + kind + 1: region 0 keeps the ids
 * 1..48 of before. */
enum gr_region { GR_CORE = 0, GR_SKIN = 1, GR_THIN = 2, GR_DOWNSKIN = 3, GR_UPSKIN = 4, GR_NREGIONS = 5 };
#define GR_REGION_IDS 48 /* ids per region: 16 lasers x 3 kinds */
static inline int gr_style_id(const gr_block *b) { return b->region * GR_REGION_IDS + b->laser * 3 + b->kind + 1; }
static inline const char *gr_region_name(int r) {
  static const char *const n[GR_NREGIONS] = {"core", "skin", "thin", "downskin", "upskin"};
  return r >= 0 && r < GR_NREGIONS ? n[r] : "?";
}
typedef struct gr_layer {
  double z;        /* CLI layer height z_k, mm (geometry from z_k - t/2) */
  double *xy;
  size_t npts, cappts;
  gr_block *b;
  size_t nb, capb;
  int thin_walls;  /* regions scanned by the thin-wall rule */
  int short_loops; /* closed contours dropped as shorter than the melt track */
  double short_length; /* their total length, mm */
  double area;     /* solid section area of the layer, mm^2 (0 if unknown) */
} gr_layer;

gr_layer *gr_layer_new(double z);
void gr_layer_free(gr_layer *l);
void gr_layer_clear(gr_layer *l, double z);
/* Append a block of n points (copied). Returns GR_OK/GR_EMEM. */
int gr_layer_add(gr_layer *l, int shape, int kind, int laser, int dir,
                 const double *xy, size_t n);
/* Append one hatch vector to the last block if it is a GR_SEGMENTS block of
 * the same kind and laser, else start a new block. */
int gr_layer_add_segment(gr_layer *l, int kind, int laser, double x0,
                         double y0, double x1, double y1);
/* The same for a segment of a region (gr_region): a new block when the
 * region changes. */
int gr_layer_add_segment_r(gr_layer *l, int kind, int region, int laser, double x0,
                           double y0, double x1, double y1);
int gr_layer_append(gr_layer *dst, const gr_layer *src, double dx, double dy);
/* Scan length of a block and of all blocks of a kind (mm). */
double gr_block_length(const gr_layer *l, const gr_block *b);
typedef struct gr_layer_stats {
  size_t vectors[GR_NKINDS];  /* scan vectors (segments) per kind */
  double length[GR_NKINDS];   /* scan length per kind, mm */
  size_t jumps;               /* moves between blocks/segments with the laser off */
  double jump_length;         /* mm, in block order */
} gr_layer_stats;
void gr_layer_stats_get(const gr_layer *l, gr_layer_stats *s);
void gr_layer_bounds(const gr_layer *l, double lo[2], double hi[2]);

#endif
