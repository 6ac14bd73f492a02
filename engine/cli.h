/* cli.h: Common Layer Interface 2.0 output and input (doc/contract.md s.6).
 * Writers stream layer by layer through gr_atomic (temporary file + rename,
 * nothing left behind on error). Build-style id of a block: laser*3 + kind + 1
 * (labels "laserN-contour|hatch|edge"). */
#ifndef GR_CLI_H
#define GR_CLI_H
#include "paths.h"

typedef struct gr_cli_header {
  int binary;        /* 0 ASCII, 1 binary (LONG commands) */
  double units;      /* mm per coordinate unit ($$UNITS), default 0.001 (um) */
  int layers;        /* $$LAYERS */
  double lo[3], hi[3]; /* $$DIMENSION, mm */
  int nlasers;       /* labels written for lasers 1..nlasers */
  int buffered;      /* writer: 1 = through the page cache only (default 0:
                        O_DIRECT where the file system allows it) */
} gr_cli_header;
gr_cli_header gr_cli_header_defaults(void);

typedef struct gr_cli_writer gr_cli_writer;
gr_cli_writer *gr_cli_open(const char *path, const gr_cli_header *h, gr_err *e);
int gr_cli_write_layer(gr_cli_writer *w, const gr_layer *l, gr_err *e);
/* commit != 0: finish and rename into place; 0: remove the temporary. Frees w. */
int gr_cli_close(gr_cli_writer *w, int commit, gr_err *e);

/* Reader: calls fn for each layer (block laser = (id-1)/3, kind = (id-1)%3).
 * Errors name the file and the line (ASCII) or byte offset (binary). */
typedef int (*gr_cli_layer_fn)(void *ud, const gr_layer *l, gr_err *e);
int gr_cli_read(const char *path, gr_cli_header *h, gr_cli_layer_fn fn, void *ud, gr_err *e);
/* The same, with the geometry taken from byte `from` on (the start of a layer
 * command or $$LAYER line, found by the caller; ASCII: `line` is its line
 * number, used in messages). from = 0 reads the whole file. fn may return
 * any non-zero code to stop early; that code is returned. */
int gr_cli_read_from(const char *path, size_t from, int line, gr_cli_header *h, gr_cli_layer_fn fn, void *ud,
                     gr_err *e);

#endif
