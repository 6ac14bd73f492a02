/* grid.h: the part's voxel grid and its layers (paper s.3.1; a stage-free
 * primitive every pipeline stage uses).
 *
 * Takes: the cell lengths Lx, Ly, Lz (equal for cubic cells), voxel counts,
 * the domain's min corner and the layer thickness t. Gives: where voxel v lies, which global layers g (1..N) fall
 * in voxel row k, and the height each layer's geometry is taken at.
 *
 * N = round(nz*Lz/t) layers; layer g has CLI height z_g = oz + g*t and its
 * geometry is taken at mid(g) = z_g - t/2. Voxel row k spans
 * [oz + k*Lz, oz + (k+1)*Lz); its first layer is g0(k), the first g with mid(g)
 * inside the row; local layer index = g - g0(k). */
#ifndef GR_GRID_H
#define GR_GRID_H

typedef struct gr_grid {
  double cell[3];    /* Lx, Ly, Lz, mm (a cube: all equal) */
  double origin[3];  /* min corner, mm */
  int n[3];          /* voxels along x, y, z */
  double layer;      /* t, mm */
  int nlayers;       /* N */
} gr_grid;

gr_grid gr_grid_make(const double cell[3], const double origin[3], const int n[3], double layer);
double gr_grid_mid(const gr_grid *g, int layer);        /* mid(g), mm */
int gr_grid_row_first(const gr_grid *g, int k);         /* g0(k) */
int gr_grid_row_layers(const gr_grid *g, int k);        /* layers of row k */
int gr_grid_layer_row(const gr_grid *g, int layer);     /* the row holding mid(g) */
void gr_grid_ijk(const gr_grid *g, int v, int *i, int *j, int *k);
void gr_grid_origin(const gr_grid *g, int v, double o[3]); /* voxel v's min corner, mm */

/* Cell helpers: 1 when Lx = Ly = Lz; the smallest of the three (mm). */
int gr_cell_cube(const double cell[3]);
double gr_cell_min(const double cell[3]);

#endif
