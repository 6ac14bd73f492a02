/* bind_ovf.h: what bind_ovf.c offers the other binding files. */
#ifndef GR_BIND_OVF_H
#define GR_BIND_OVF_H
#include "bind.h"
#include "ovf.h"
#include "place.h"
/* An OVF writer for job:run from its option table at index opts (styles,
 * name, jump_delay, polygon_delay) and the job's strategy. */
gr_ovf_writer *gr_lua_ovf_open(lua_State *L, int opts, const char *path, const gr_job_opts *o, int layers, gr_err *e);
/* gradus.info(path) / gradus.cli.info(path) */
int gr_l_info(lua_State *L);
int gr_open_ovf(lua_State *L); /* gradus.info, gradus.convert, gradus.ovf.* */
#endif
