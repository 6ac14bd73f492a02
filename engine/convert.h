/* convert.h: machine file conversion (gradus convert): any file the reader of
 * cli.h takes (CLI ASCII or binary, long or short commands; OVF) to CLI ASCII,
 * CLI binary (long commands) or OVF. Geometry is kept to float32 precision;
 * layers, blocks, lasers and kinds are kept; the build styles' names and
 * parameters go into OVF marking parameter sets (a CLI output has no place
 * for them: its labels are laserN-kind). Output through a temporary file:
 * on any error nothing is written. */
#ifndef GR_CONVERT_H
#define GR_CONVERT_H
#include "cli.h"

enum { GR_FMT_ASCII = 0, GR_FMT_BINARY = 1, GR_FMT_OVF = 2 };
/* The output format: name ("ascii", "binary", "ovf"), or when name is NULL
 * or "" from path's extension (.ovf: OVF, .cli: binary CLI). */
int gr_convert_format(const char *name, const char *path, int *fmt, gr_err *e);
int gr_convert(const char *in, const char *out, int fmt, gr_err *e);

#endif
