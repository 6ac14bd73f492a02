/* view.h: the data behind `gradus view`: an index of a CLI file's layers
 * (random access to layer k through the CLI reader) and the compact layer
 * encoding the browser page decodes (doc/formats.md, "Viewer layer data"). */
#ifndef GR_VIEW_H
#define GR_VIEW_H
#include "cli.h"

/* Where each layer starts. Built by one pass over the mapped file that only
 * reads command heads (binary) or line starts (ASCII); nothing of the
 * geometry stays in memory: 24 bytes per layer. Read-only once built, so
 * several threads may read layers through it at once. */
typedef struct gr_view_entry {
  size_t at;           /* byte offset of the layer's command or $$LAYER line */
  int line;            /* ASCII: line number of that line; binary: 0 */
  double z;            /* layer height, mm */
} gr_view_entry;
typedef struct gr_view_index {
  char *path;          /* the CLI file (copied) */
  gr_cli_header h;     /* as the reader saw it */
  size_t n, cap;       /* layers found, capacity */
  gr_view_entry *layer;
  size_t bytes;        /* file size */
} gr_view_index;

/* Errors: a missing or non-CLI file, a truncated command or an unknown one
 * (binary, naming the byte offset), no layer at all. */
gr_view_index *gr_view_index_open(const char *path, gr_err *e);
void gr_view_index_free(gr_view_index *ix); /* NULL is fine */

/* Read layer k (0-based, k < ix->n) through the CLI reader and hand it to fn. */
int gr_view_layer(const gr_view_index *ix, size_t k, gr_cli_layer_fn fn, void *ud, gr_err *e);

/* A growable byte buffer; free(p) releases it. */
typedef struct gr_view_buf {
  unsigned char *p;
  size_t n, cap;
} gr_view_buf;

/* Append layer l to b in the viewer's encoding: unsigned LEB128 varints
 * (signed values zigzag), coordinates rounded to multiples of `quantum` mm
 * and each point stored as the difference from the one before:
 *   version (1), z, block count, per block: id, kind, laser, shape, dir,
 *   points; then every point's dx, dy in block order.
 * The id is the CLI build-style id as the reader maps it (laser*3 + kind + 1).
 * Errors: GR_ENUM for a coordinate that is not finite or beyond 2^50
 * quanta, GR_EMEM. */
int gr_view_encode(const gr_layer *l, double quantum, gr_view_buf *b, gr_err *e);

/* Base64 (RFC 4648, with padding) of n bytes; a NUL-terminated string the
 * caller frees, or NULL when out of memory. */
char *gr_view_base64(const unsigned char *p, size_t n, size_t *outlen);

#endif
