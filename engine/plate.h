/* plate.h: a build plate of several parts in one CLI.
 *
 * Each part is a CLI file of its own (written by a gradus job in the part's
 * own coordinates). gr_plate_add reads it and places it on the plate: every
 * point q goes to  at + R(angle) (q - c),  where c is the centre of the
 * part's x-y extent (its $$DIMENSION, else the box of its vectors) and R the
 * rotation about z by `angle` degrees (counter-clockwise seen from above).
 * The placed part's footprint is the convex hull of all its vectors over
 * all layers (gr_plate_hull); two footprints that overlap are found by
 * gr_plate_overlap (separating axes, exact for convex polygons).
 * gr_plate_write merges the parts by z into one CLI: plate layer g
 * (z = floor + g * t, floor the lowest part's $$DIMENSION z min) holds every
 * part's layer at that height. A part whose layers are off that grid (another
 * layer thickness) is refused by name. Nothing is written on any error.
 *
 * Memory: the placed parts' vectors are held in memory until written (each
 * part layer is freed as soon as it has gone to the output). Not thread-safe;
 * one gr_plate per thread. */
#ifndef GR_PLATE_H
#define GR_PLATE_H
#include "paths.h"

typedef struct gr_plate gr_plate;

gr_plate *gr_plate_new(void);
void gr_plate_free(gr_plate *p); /* NULL is fine */

/* Read the part CLI `path` (ASCII, binary or OVF: gr_cli_read) and place it.
 * `name` is used in messages. Returns GR_OK; errors name the part. */
int gr_plate_add(gr_plate *p, const char *path, const char *name, double at_x, double at_y, double angle_deg,
                 gr_err *e);
int gr_plate_count(const gr_plate *p);

typedef struct gr_plate_part_info {
  int layers;        /* layers read */
  int lasers;        /* 1 + the highest laser index used (0: no vectors) */
  double zlo, zhi;   /* $$DIMENSION z range of the part (mm) */
  double centre[2];  /* c: the centre of its own x-y extent (mm, own coordinates) */
  double lo[2], hi[2]; /* box of the placed footprint (mm, plate coordinates) */
  double length;     /* scan length of all its vectors (mm) */
} gr_plate_part_info;
int gr_plate_part(const gr_plate *p, int i, gr_plate_part_info *info); /* i 0-based; GR_EARG if out of range */

/* The placed footprint of part i: n points (x, y pairs, mm), counter-
 * clockwise, owned by p. n < 3 for a part with (almost) no vectors. */
const double *gr_plate_hull(const gr_plate *p, int i, size_t *n);

/* 1 when the footprints of parts i and j overlap by more than tol (mm),
 * 0 when they are apart or only touch. */
int gr_plate_overlap(const gr_plate *p, int i, int j, double tol);
/* The same for two convex polygons (x, y pairs, either orientation). */
int gr_plate_poly_overlap(const double *a, size_t na, const double *b, size_t nb, double tol);

/* Part i's laser k (0-based) is written as laser map[k]; n entries, every
 * laser the part uses must be mapped (else GR_EARG naming the laser). */
int gr_plate_map_lasers(gr_plate *p, int i, const int *map, int n, gr_err *e);

typedef struct gr_plate_opts {
  double layer_mm;   /* the plate's layer thickness t (> 0) */
  int binary;        /* 0 ASCII, 1 binary CLI */
  int short_form;    /* binary: short commands where they fit */
  double units;      /* mm per coordinate unit (> 0) */
  int nlasers;       /* $$LABEL lines for lasers 1..nlasers */
  int keep;          /* plate layer number to hand back (gr_plate_info.kept), 0: none */
} gr_plate_opts;

typedef struct gr_plate_info {
  int layers;        /* plate layers written (1 .. the tallest part's top) */
  double lo[3], hi[3]; /* $$DIMENSION written: x-y box of every placed vector (the hulls), floor to top (mm) */
  long blocks;       /* blocks written */
  double length;     /* scan length written (mm) */
  gr_layer *kept;    /* a copy of layer opts.keep (caller frees), or NULL */
  char form[16];     /* what the writer wrote: ascii, long, short, short+long */
  long rounded_points, rounded_vectors; /* left out by the short form (gr_cli_rounded) */
} gr_plate_info;

/* Merge every part into the CLI `out`. Can be called once per plate (the
 * parts' layers are released as they are written). */
int gr_plate_write(gr_plate *p, const char *out, const gr_plate_opts *o, gr_plate_info *info, gr_err *e);

#endif
