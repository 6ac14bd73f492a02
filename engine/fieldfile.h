/* fieldfile.h: scalar fields read from files and interpolated trilinearly:
 * VTK legacy STRUCTURED_POINTS (ASCII, or BINARY big-endian float/double, as
 * ParaView and FE codes write them) and NumPy .npy (3-D float32/float64,
 * little- or big-endian, C or Fortran order; a[i,j,k] is the value at
 * origin + (i*sx, j*sy, k*sz)). Values must be finite. */
#ifndef GR_FIELDFILE_H
#define GR_FIELDFILE_H
#include "field.h"

typedef struct gr_fieldfile_opts {
  double origin[3];  /* .npy: grid origin, mm (VTK: from the file) */
  double spacing[3]; /* .npy: grid spacing, mm, > 0 (VTK: from the file) */
  double pad;        /* points up to this far outside the grid (mm) take the
                        nearest grid value; farther ones are an error */
} gr_fieldfile_opts;
gr_fieldfile_opts gr_fieldfile_defaults(void); /* origin 0, spacing 0 (unset), pad 0 */

/* Read path (format from the file's first bytes). Errors name the file and,
 * for bad data, the index (i, j, k) or the byte offset: truncated data, NaN or
 * infinite values, a shape that is not 3-D or does not match DIMENSIONS, an
 * unsupported type. Evaluating the field outside the grid (beyond pad) is a
 * GR_EARG error naming the file, the point and the grid's extent. */
gr_field *gr_field_file(const char *path, const gr_fieldfile_opts *o, gr_err *e);

/* Grid facts of a file field: samples per axis and extent (mm). 0 if f is
 * not one. */
int gr_fieldfile_info(const gr_field *f, int n[3], double lo[3], double hi[3]);

#endif
