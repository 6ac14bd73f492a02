/* cli.h: Common Layer Interface 2.0 output and input (doc/contract.md s.6), and the
 * reader of every machine file Gradus knows (CLI ASCII, binary long and short
 * form, Open Vector Format: see ovf.h).
 * Writers stream layer by layer through gr_atomic (temporary file + rename,
 * nothing left behind on error). Build-style id of a block: laser*3 + kind + 1
 * (labels "laserN-contour|hatch|edge"). */
#ifndef GR_CLI_H
#define GR_CLI_H
#include "paths.h"

#define GR_CLI_MAXSTYLES 256

/* A build style as a reader found it: a CLI id with the parameter commands
 * ($$POWER, $$SPEED, $$FOCUS) in force before the block, or an OVF marking
 * parameter set. Unknown values are NaN. */
typedef struct gr_cli_style {
  int id;            /* CLI build-style id / OVF marking_params_key */
  double power;      /* W */
  double speed;      /* mm/s */
  double focus;      /* focus shift, mm */
  double jump_speed; /* mm/s */
  char name[64];     /* the header's $$LABEL text, the OVF name, or "laserN-kind" */
} gr_cli_style;

/* A $$LABEL/id,text line of a CLI header, text as written. */
typedef struct gr_cli_label { int id; char text[60]; } gr_cli_label;

typedef struct gr_cli_header {
  int binary;        /* 0 ASCII, 1 binary (LONG commands; a reader sets it for
                        short commands too and counts them in `short_cmds`) */
  double units;      /* mm per coordinate unit ($$UNITS), default 0.001 (um) */
  int layers;        /* $$LAYERS */
  double lo[3], hi[3]; /* $$DIMENSION, mm */
  int nlasers;       /* labels written for lasers 1..nlasers */
  int regions;       /* writer: bit r set = labels of region r (paths.h gr_region) written too */
  int buffered;      /* writer: 1 = through the page cache only (default 0:
                        O_DIRECT where the file system allows it) */
  int short_form;    /* writer, binary: 1 = short commands (128, 129, 131:
                        uint16 coordinates, values rounded to whole units)
                        where they fit, long ones elsewhere */
  /* filled by the readers only: */
  int ovf;           /* 1: the file was an Open Vector Format job */
  long short_cmds;   /* binary short-form commands (128, 129, 131) read */
  int nlabels;
  gr_cli_label label[GR_CLI_MAXSTYLES]; /* the header's $$LABEL lines */
  int nstyles;
  gr_cli_style style[GR_CLI_MAXSTYLES]; /* build styles met so far (see gr_cli_read_ex) */
} gr_cli_header;
gr_cli_header gr_cli_header_defaults(void);

typedef struct gr_cli_writer gr_cli_writer;
gr_cli_writer *gr_cli_open(const char *path, const gr_cli_header *h, gr_err *e);
int gr_cli_write_layer(gr_cli_writer *w, const gr_layer *l, gr_err *e);
/* What was written so far: "ascii", "long" (binary long commands), "short"
 * (every geometry command short) or "short+long" (some did not fit). */
const char *gr_cli_form(const gr_cli_writer *w);
/* What the short form left out so far: polyline points equal to the one
 * before them once rounded to the unit, hatch vectors that rounded to one
 * point (zero-length marks; a polyline that rounds to one point stays a dot). */
void gr_cli_rounded(const gr_cli_writer *w, long *points, long *vectors);
/* commit != 0: finish and rename into place; 0: remove the temporary. Frees w. */
int gr_cli_close(gr_cli_writer *w, int commit, gr_err *e);

/* Reader: calls fn for each layer (block kind = (id-1)%3, laser = (id-1)/3
 * mod 16, region = (id-1)/48: paths.h gr_style_id).
 * Errors name the file and the line (ASCII) or byte offset (binary). */
typedef int (*gr_cli_layer_fn)(void *ud, const gr_layer *l, gr_err *e);
int gr_cli_read(const char *path, gr_cli_header *h, gr_cli_layer_fn fn, void *ud, gr_err *e);
/* The same, with the geometry taken from byte `from` on (the start of a layer
 * command or $$LAYER line, found by the caller; ASCII: `line` is its line
 * number, used in messages). from = 0 reads the whole file. fn may return
 * any non-zero code to stop early; that code is returned. */
int gr_cli_read_from(const char *path, size_t from, int line, gr_cli_header *h, gr_cli_layer_fn fn, void *ud,
                     gr_err *e);

/* The same with each block's build style: style[b] indexes h->style for
 * block b of l (h->nstyles grows while reading as parameter commands make new
 * combinations). Reads CLI (ASCII; binary, long and short commands) and OVF
 * (by its magic "LVF!"); gr_cli_read does the same. */
typedef int (*gr_cli_layer_ex_fn)(void *ud, const gr_layer *l, const int *style, const gr_cli_header *h,
                                  gr_err *e);
int gr_cli_read_ex(const char *path, gr_cli_header *h, gr_cli_layer_ex_fn fn, void *ud, gr_err *e);
/* Both readers on bytes in memory (name is used in messages). */
int gr_cli_read_mem(const char *name, const unsigned char *t, size_t len, gr_cli_header *h,
                    gr_cli_layer_ex_fn fn, void *ud, gr_err *e);
/* Map path read-only (*map NULL for an empty file; munmap(*map, *len)). */
int gr_cli_map(const char *path, void **map, size_t *len, gr_err *e);
/* Index of (id, power, speed, focus) in h->style, added if new (name from the
 * header's label of id, else "laserN-kind"); -1 when the table is full. */
int gr_cli_style_index(gr_cli_header *h, int id, double power, double speed, double focus);

#endif
