/* grid.c: the voxel grid and its layers, see grid.h. */
#include "grid.h"
#include <math.h>

gr_grid gr_grid_make(const double cell[3], const double origin[3], const int n[3], double layer) {
  gr_grid g;
  g.layer = layer;
  for (int a = 0; a < 3; a++) {
    g.origin[a] = origin[a];
    g.n[a] = n[a];
    g.cell[a] = cell[a];
  }
  g.nlayers = (int)lround(n[2] * cell[2] / layer);
  return g;
}

double gr_grid_mid(const gr_grid *g, int layer) {
  return g->origin[2] + (layer - 0.5) * g->layer;
}

int gr_grid_row_first(const gr_grid *g, int k) {
  double z0 = k * g->cell[2];
  int l = (int)ceil(z0 / g->layer + 0.5 - 1e-9);
  return l < 1 ? 1 : l;
}

int gr_grid_row_layers(const gr_grid *g, int k) {
  int g0 = gr_grid_row_first(g, k);
  int last = (int)ceil(((k + 1) * g->cell[2]) / g->layer + 0.5 - 1e-9) - 1;
  if (last > g->nlayers) last = g->nlayers;
  return last >= g0 ? last - g0 + 1 : 0;
}

int gr_grid_layer_row(const gr_grid *g, int layer) {
  int k = (int)floor((gr_grid_mid(g, layer) - g->origin[2]) / g->cell[2]);
  if (k < 0) k = 0;
  if (k >= g->n[2]) k = g->n[2] - 1;
  return k;
}

void gr_grid_ijk(const gr_grid *g, int v, int *i, int *j, int *k) {
  *i = v % g->n[0];
  *j = (v / g->n[0]) % g->n[1];
  *k = v / (g->n[0] * g->n[1]);
}

void gr_grid_origin(const gr_grid *g, int v, double o[3]) {
  int i, j, k;
  gr_grid_ijk(g, v, &i, &j, &k);
  o[0] = g->origin[0] + i * g->cell[0];
  o[1] = g->origin[1] + j * g->cell[1];
  o[2] = g->origin[2] + k * g->cell[2];
}

int gr_cell_cube(const double cell[3]) { return cell[0] == cell[1] && cell[1] == cell[2]; }

double gr_cell_min(const double cell[3]) { return fmin(cell[0], fmin(cell[1], cell[2])); }
