/* clicat.h: merge CLI part files into one CLI, byte for byte.
 *
 * The parts are consecutive layer ranges of one job, each written by the
 * gradus CLI writer (cli.h), e.g. by `gradus run ... -D layers=a:b` on
 * several machines. The merge keeps the first part's header with $$LAYERS
 * rewritten to the total and concatenates the parts' geometry sections
 * unchanged, so the result is the file a single run over all layers writes.
 *
 * Each part is read once through gr_cli_read (which checks it and gives its
 * layer table: the z of every layer); a layer's number is its height above
 * the part's $$DIMENSION floor in layer thicknesses (the thickness is the
 * spacing of consecutive layers). Parts may be given in any order; they are
 * sorted by their first layer. Refused, with the file names and layer
 * numbers: a part with no layers, parts of different jobs (headers that
 * differ in more than $$LAYERS and $$DATE), ASCII mixed with binary, layers
 * off the layer grid or not consecutive inside a part, and a gap or an
 * overlap between parts. Nothing is written on any error (gr_atomic). */
#ifndef GR_CLICAT_H
#define GR_CLICAT_H
#include "common.h"

typedef struct gr_clicat_info {
  int layers;       /* layers written */
  int first, last;  /* their numbers (1 = the first layer above the floor) */
  double layer_mm;  /* the layer thickness found */
} gr_clicat_info;

/* Merge the n >= 1 parts into `out` (which must not be one of the parts). */
int gr_cli_cat(const char *const *parts, int n, const char *out, gr_clicat_info *info, gr_err *e);

#endif
