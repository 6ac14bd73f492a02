/* place.h: part-scale placement (paper sections 3.1 and 4). A job is a grid
 * of voxels, each filled with one graded TPMS cell described by a spec. Voxels
 * are grouped into classes by signature; each class's toolpaths are built once
 * as a template (or loaded from the knowledge base) and populated, translated,
 * into every voxel of the class. Layers are then streamed: contours joined
 * across voxels, hatches generated on a global line family and joined across
 * voxels (continuous mode) or kept per voxel (island mode), ordered by the
 * fabrication sequence, assigned to lasers, and written in order. */
#ifndef GR_PLACE_H
#define GR_PLACE_H
#include "field.h"
#include "paths.h"

#define GR_MAX_LASERS 16
/* Voxels a job holds at most: 1e8 (about 2 GB of per-voxel state, and a
 * 928 mm cube of 2 mm cells, beyond any powder bed); cells of 1000 x 1000 x
 * 1000 (10 x 10 x 10 meant) are refused at once instead of allocating. */
#define GR_MAX_VOXELS 1e8
/* Default overlap of two lasers' scans where they meet, mm: a moderate
 * overlap (source in doc/formats.md, machine profile). */
#define GR_STITCH_DEFAULT 0.5
enum { GR_PATTERN_PARALLEL = 0, GR_PATTERN_ZIGZAG = 1, GR_PATTERN_ISLAND = 2 };

/* The machine: lasers with reachable fields and speeds per vector kind. */
typedef struct gr_machine {
  int n;                                  /* lasers */
  double speed[GR_MAX_LASERS][GR_NKINDS]; /* scan speed per kind, mm/s */
  double lo[GR_MAX_LASERS][2];            /* reachable field, mm (-inf = none) */
  double hi[GR_MAX_LASERS][2];
  double jump_speed;                      /* mm/s */
  double jump_delay;                      /* s per jump */
  double polygon_delay;                   /* s per block */
  double recoat_time;                     /* s per layer */
  double stitch;                          /* overlap where two lasers meet, mm (stitch.h) */
  double rspeed[GR_NREGIONS];             /* scan speed of regions 1.. (regions.h), mm/s */
} gr_machine;
gr_machine gr_machine_default(int n);

/* What a run produced (doc/contract.md section 8). */
typedef struct gr_job_stats {
  int layers;                  /* layers written */
  int voxels;                  /* voxels with a lattice */
  int trimmed;                 /* of which cut by the domain boundary */
  int trimmed_classes;         /* their templates (shared where the domain's boundary repeats) */
  int classes;                 /* unique voxel classes (templates) */
  int built;                   /* templates computed in this run */
  int reused;                  /* templates loaded from the knowledge base */
  int kb_corrupt;              /* knowledge-base records found corrupt (rebuilt) */
  int kb_stored;               /* templates written to the knowledge base */
  int kb_not_stored;           /* built but not written (kb_store policy) */
  int held_max;                /* most templates held in memory at once (streaming) */
  int banded_rows;             /* rows whose templates were built a band of layers at a time */
  size_t vectors[GR_NKINDS];   /* scan vectors per kind */
  double length[GR_NKINDS];    /* scan length per kind, mm */
  size_t jumps;                /* jumps (all lasers) */
  double jump_length;          /* mm */
  double laser_time[GR_MAX_LASERS];   /* estimated scan time per laser, s */
  double laser_length[GR_MAX_LASERS]; /* scan length per laser, mm */
  double build_time;           /* sum over layers of the slowest laser, plus recoating, s */
  double jump_time;            /* all lasers' jumps and delays, s (part of their times) */
  double recoat_time;          /* recoating, s (layers x the machine's recoat time) */
  double balanced_time;        /* the same with perfect balance, s */
  long thin_walls;             /* regions scanned by the thin-wall rule */
  int verified;                /* templates verified in this run (opts.verify) */
  int unqualified;             /* templates failing qualification (built, or stored so) */
  char unqualified_why[256];   /* the last one's reason */
  long dropped;                /* hatch vectors below the minimum length */
  long split_loops;            /* closed contours no single laser reaches, split with overlap */
  long short_loops;            /* closed contours shorter than the melt track, dropped */
  double short_length;         /* their total length, mm */
  double solid_area;           /* sum over layers of the section area, mm^2 */
  size_t region_vectors[GR_NREGIONS]; /* scan vectors per region (regions.h) */
  double region_length[GR_NREGIONS];  /* scan length per region, mm */
  double region_time[GR_NREGIONS];    /* marking time per region (no jumps), s */
  double seconds[4];           /* wall time: classify, templates, layers, total */
} gr_job_stats;

/* What fills a voxel: one graded TPMS cell. */
typedef struct gr_spec {
  int surface;          /* TPMS catalogue index (field.h) */
  double level;         /* c */
  int network;          /* 0 sheet, 1 network */
  int side;             /* network side: -1 (phi < c, default) or +1 */
  char thickness[512];  /* half-thickness T: expression in x,y,z,u,v,w,L,Lx,Ly,Lz (mm) */
  char inside[512];     /* optional inside thickness (asymmetric sheet), "" = T */
  struct gr_dtable *density; /* or NULL: thickness values are densities (density.h) */
  gr_field *target;     /* or NULL: a field of x,y,z used instead of the expression
                           (both owned by the caller, alive while the job is) */
} gr_spec;

/* Process and strategy parameters of a job (the signature includes those
 * that change a template). */
typedef struct gr_job_opts {
  double cell[3];       /* voxel = unit cell lengths Lx, Ly, Lz, mm (a cube: all
                           equal; stretched cells tile the stretched surface) */
  double origin[3];     /* domain min corner, mm */
  int n[3];             /* voxels along x, y, z */
  double layer;         /* layer thickness t, mm */
  double hatch;         /* hatch spacing d, mm */
  double beam_offset;   /* contour offset b, mm (default d/2) */
  double track;         /* melt track width for verify, mm (default d) */
  int contours;         /* contour scans per boundary (>= 0) */
  int contour_first;    /* 1: contours before hatches */
  double angle;         /* first hatch angle, degrees */
  double rotation;      /* degrees added per layer */
  int pattern;          /* 0 parallel (joined across voxels), 1 zigzag, 2 island */
  int alternate;        /* reverse every other hatch vector */
  double slice_cell;    /* marching-squares cell, mm (<= d/2, eq. 7) */
  int res;              /* samples per cell edge for the marching-cubes H */
  int exact;            /* 1: distance mode exact, 0: mesh */
  double quant;         /* thickness quantisation of signatures, mm (1e-3 = 1 um) */
  double min_length;    /* hatch vectors shorter than this are dropped, mm */
  int threads;          /* worker threads (>= 1) */
  int verify;           /* 1: verify() every layer of each template built
                           (pore, overmelt, contour deviation) and qualify it */
  double max_pore;      /* qualification: worst layer pore fraction (0.005) */
  double max_overmelt;  /* qualification: worst layer overmelt fraction (0.01) */
  double max_dev;       /* qualification: contour deviation, mm (0.001) */
  int nlasers;          /* lasers (the machine may replace it) */
  int share;            /* 1: classes differing only in T share closest points
                           (same result, much faster); 0: each class alone */
  int faces;            /* 1: where the lattice is cut by the part's box (a voxel
                           side with no lattice beyond), contours run along the
                           cut and hatches stop at the hatch offset from it;
                           0: the cut is left open (hatched up to the side) */
} gr_job_opts;
gr_job_opts gr_job_defaults(void);

typedef struct gr_job gr_job;
gr_job *gr_job_new(const gr_job_opts *o, gr_err *e);
/* GR_EARG (the count, the limit and the part's size in the message) when n
 * cells along x, y, z of size cell are more voxels than GR_MAX_VOXELS. */
int gr_job_check_size(const int n[3], const double cell[3], gr_err *e);
void gr_job_free(gr_job *j);
/* Add a spec; returns its index (>= 0) or -1 with e set. */
int gr_job_add_spec(gr_job *j, const gr_spec *s, gr_err *e);
/* Set voxel (i,j,k)'s spec (-1 = empty), laser (-1 = by strategy) and
 * sequence key (smaller first). Voxels default to spec 0, laser -1, raster. */
int gr_job_set_voxel(gr_job *j, int i, int jj, int k, int spec, int laser,
                     double seq, gr_err *e);
/* Optional design domain {domain < 0} (new reference taken) and skin. Voxels
 * wholly outside are skipped; voxels cut by the boundary are computed
 * directly (trimmed), the others use templates. */
int gr_job_set_domain(gr_job *j, gr_field *domain, double skin, gr_err *e);

int gr_job_set_machine(gr_job *j, const gr_machine *m, gr_err *e);

typedef int (*gr_layer_sink)(void *ud, int g, const gr_layer *l, gr_err *e);
typedef void (*gr_progress_fn)(void *ud, const char *stage, long done, long total);
/* A recipe's qualification rule: quality = {worst pore, worst overmelt,
 * max contour deviation mm, layers verified} (NaN when not verified),
 * thin_walls = thin-wall scans in the template. Returns 1 (qualified) or 0,
 * with a reason in why. Called on the calling thread. */
typedef int (*gr_qualify_fn)(void *ud, const char *key, const double quality[4], long thin_walls,
                             char *why, size_t n);
typedef struct gr_kb gr_kb;
/* Which built templates go to the knowledge base (kb_store=): */
enum gr_kb_store {
  GR_KB_STORE_REUSED = 0,  /* those of classes with more than one voxel (default) */
  GR_KB_STORE_ALL = 1,     /* every one (trimmed classes are never stored) */
  GR_KB_STORE_NONE = 2     /* none: the knowledge base is only read */
};
typedef struct gr_job_run_opts {
  gr_kb *kb;               /* knowledge base, or NULL */
  int kb_store;            /* enum gr_kb_store */
  int direct;              /* 1: kb=off, every voxel computed directly */
  int first, last;         /* layer range, 1-based inclusive; 0 = all */
  gr_layer_sink sink;      /* receives each layer in order (main thread) */
  void *sink_ud;
  gr_progress_fn progress; /* called from the calling thread only */
  void *progress_ud;
  gr_qualify_fn qualify;   /* extra qualification rule, or NULL */
  void *qualify_ud;
} gr_job_run_opts;
/* Classify, build or load templates, and stream the layers to the sink. */
int gr_job_run(gr_job *j, const gr_job_run_opts *r, gr_err *e);
int gr_job_classify(gr_job *j, int direct, gr_err *e);
const gr_job_stats *gr_job_get_stats(const gr_job *j);
const char *gr_job_warning(const gr_job *j);   /* last knowledge-base warning or "" */
int gr_job_layers(const gr_job *j);            /* N */
int gr_job_classes(const gr_job *j);
const char *gr_job_class_key(const gr_job *j, int c);
const gr_job_opts *gr_job_options(const gr_job *j);
double gr_job_angle(const gr_job *j, int g);   /* hatch angle of layer g, degrees */
double gr_layer_angle(const gr_job_opts *o, int g); /* the same from the options */

#endif
