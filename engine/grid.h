/* grid.h: the part's voxel grid and its layers (paper s.3.1; a stage-free
 * primitive every pipeline stage uses).
 *
 * Takes: cell size L, voxel counts, the domain's min corner and the layer
 * thickness t. Gives: where voxel v lies, which global layers g (1..N) fall
 * in voxel row k, and the height each layer's geometry is taken at.
 *
 * N = round(nz*L/t) layers; layer g has CLI height z_g = oz + g*t and its
 * geometry is taken at mid(g) = z_g - t/2. Voxel row k spans
 * [oz + k*L, oz + (k+1)*L); its first layer is g0(k), the first g with mid(g)
 * inside the row; local layer index = g - g0(k). */
#ifndef GR_GRID_H
#define GR_GRID_H

typedef struct gr_grid {
  double cell;       /* L, mm */
  double origin[3];  /* min corner, mm */
  int n[3];          /* voxels along x, y, z */
  double layer;      /* t, mm */
  int nlayers;       /* N */
} gr_grid;

gr_grid gr_grid_make(double cell, const double origin[3], const int n[3], double layer);
double gr_grid_mid(const gr_grid *g, int layer);        /* mid(g), mm */
int gr_grid_row_first(const gr_grid *g, int k);         /* g0(k) */
int gr_grid_row_layers(const gr_grid *g, int k);        /* layers of row k */
int gr_grid_layer_row(const gr_grid *g, int layer);     /* the row holding mid(g) */
void gr_grid_ijk(const gr_grid *g, int v, int *i, int *j, int *k);
void gr_grid_origin(const gr_grid *g, int v, double o[3]); /* voxel v's min corner, mm */

#endif
