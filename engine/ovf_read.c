/* ovf_read.c: the Open Vector Format reader of ovf.h. A work plane is found
 * through the job LUT (its start), the int64 there (its LUT), the LUT (its
 * shell and blocks): nothing else of the file is parsed. Every position and
 * length is checked against the file before it is used; messages are
 * decoded by protobuf-c. Errors name the file and the byte offset. */
#include "ovf.h"
#include "ovf.pb-c.h"
#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>

struct gr_ovf_file {
  char name[4096];
  const unsigned char *t;
  size_t len;
  void *map;                    /* when opened by path */
  OpenVectorFormat__JobLUT *lut;
  gr_cli_style *style;          /* the job shell's marking parameter sets */
  int nstyles;
  double lo[2], hi[2];          /* the job's bounds, mm (0 if absent) */
};

static int64_t rd_i64(const unsigned char *p) {
  uint64_t u = 0;
  for (int i = 7; i >= 0; i--) u = (u << 8) | p[i];
  return (int64_t)u;
}

/* The delimited message of type d at byte pos (what = its name for errors). */
static void *read_msg(const gr_ovf_file *f, int64_t pos, const ProtobufCMessageDescriptor *d, const char *what,
                      gr_err *e) {
  if (pos < 12 || (uint64_t)pos >= f->len)
    return gr_fail(e, GR_EPARSE, "%s: byte %lld: %s position outside the file (%zu bytes)", f->name, (long long)pos,
                   what, f->len), NULL;
  size_t p = (size_t)pos;
  uint32_t n = 0;
  for (int k = 0;; k++) {
    if (p >= f->len) return gr_fail(e, GR_EPARSE, "%s: byte %lld: %s length runs past the end of the file", f->name, (long long)pos, what), NULL;
    if (k == 5) return gr_fail(e, GR_EPARSE, "%s: byte %lld: %s length is a varint that never ends", f->name, (long long)pos, what), NULL;
    unsigned char c = f->t[p++];
    n |= (uint32_t)(c & 127) << (7 * k);
    if (!(c & 128)) break;
  }
  if (n > f->len - p)
    return gr_fail(e, GR_EPARSE, "%s: byte %lld: %s of %u bytes runs past the end of the file", f->name, (long long)pos, what, n), NULL;
  void *m = protobuf_c_message_unpack(d, NULL, n, f->t + p);
  if (!m) return gr_fail(e, GR_EPARSE, "%s: byte %zu: malformed %s message (%u bytes)", f->name, p, what, n), NULL;
  return m;
}

static void set_style(gr_cli_style *s, const OpenVectorFormat__Job__MarkingParamsMapEntry *en) {
  memset(s, 0, sizeof *s);
  const OpenVectorFormat__MarkingParams *m = en->value;
  s->id = en->key;
  s->power = m ? m->laser_power_in_w : NAN;
  s->speed = m ? m->laser_speed_in_mm_per_s : NAN;
  s->focus = m ? m->laser_focus_shift_in_mm : NAN;
  s->jump_speed = m ? m->jump_speed_in_mm_s : NAN;
  if (m && m->name && m->name[0]) snprintf(s->name, sizeof s->name, "%s", m->name);
  else snprintf(s->name, sizeof s->name, "key%d", en->key);
}

/* The job shell: marking parameter sets and bounds. */
static int read_shell(gr_ovf_file *f, gr_err *e) {
  OpenVectorFormat__Job *job = read_msg(f, f->lut->jobshellposition, &open_vector_format__job__descriptor, "job shell", e);
  if (!job) return e->code;
  if (job->n_marking_params_map > GR_CLI_MAXSTYLES) {
    protobuf_c_message_free_unpacked(&job->base, NULL);
    return gr_fail(e, GR_EPARSE, "%s: %zu marking parameter sets (at most %d)", f->name, job->n_marking_params_map, GR_CLI_MAXSTYLES);
  }
  f->style = calloc(job->n_marking_params_map + 1, sizeof *f->style);
  if (!f->style) { protobuf_c_message_free_unpacked(&job->base, NULL); return gr_fail(e, GR_EMEM, "out of memory"); }
  for (size_t i = 0; i < job->n_marking_params_map; i++) set_style(&f->style[f->nstyles++], job->marking_params_map[i]);
  const OpenVectorFormat__AxisAlignedBox2D *b = job->job_meta_data ? job->job_meta_data->bounds : NULL;
  if (b) {
    f->lo[0] = b->x_min; f->lo[1] = b->y_min;
    f->hi[0] = b->x_max; f->hi[1] = b->y_max;
  }
  protobuf_c_message_free_unpacked(&job->base, NULL);
  return GR_OK;
}

gr_ovf_file *gr_ovf_open_mem(const char *name, const unsigned char *t, size_t len, gr_err *e) {
  if (len < 12 || memcmp(t, GR_OVF_MAGIC, 4))
    return gr_fail(e, GR_EPARSE, "%s: byte 0: not an OVF file (no magic \"LVF!\" and job LUT position)", name), NULL;
  gr_ovf_file *f = calloc(1, sizeof *f);
  if (!f) return gr_fail(e, GR_EMEM, "out of memory"), NULL;
  snprintf(f->name, sizeof f->name, "%s", name);
  f->t = t;
  f->len = len;
  f->lut = read_msg(f, rd_i64(t + 4), &open_vector_format__job_lut__descriptor, "job LUT", e);
  if (!f->lut || read_shell(f, e)) { gr_ovf_free(f); return NULL; }
  return f;
}

gr_ovf_file *gr_ovf_open_read(const char *path, gr_err *e) {
  void *map;
  size_t len;
  if (gr_cli_map(path, &map, &len, e)) return NULL;
  static const unsigned char none[1] = {0};
  gr_ovf_file *f = gr_ovf_open_mem(path, map ? map : none, len, e);
  if (!f) { if (map) munmap(map, len); return NULL; }
  f->map = map;
  return f;
}

void gr_ovf_free(gr_ovf_file *f) {
  if (!f) return;
  if (f->lut) protobuf_c_message_free_unpacked(&f->lut->base, NULL);
  if (f->map) munmap(f->map, f->len);
  free(f->style);
  free(f);
}

int gr_ovf_planes(const gr_ovf_file *f) { return (int)f->lut->n_workplanepositions; }

void gr_ovf_header(const gr_ovf_file *f, gr_cli_header *h) {
  *h = gr_cli_header_defaults();
  h->ovf = 1;
  h->binary = 1;
  h->units = 1;
  h->nlasers = 0;
  h->layers = gr_ovf_planes(f);
  h->lo[0] = f->lo[0]; h->lo[1] = f->lo[1];
  h->hi[0] = f->hi[0]; h->hi[1] = f->hi[1];
  for (int i = 0; i < f->nstyles; i++) h->style[h->nstyles++] = f->style[i];
}

static double ring_area(const float *p, size_t n) {
  double a = 0;
  for (size_t i = 0; i + 1 < n; i++) a += (double)p[2 * i] * p[2 * i + 3] - (double)p[2 * i + 2] * p[2 * i + 1];
  return a / 2;
}

/* Block vb (read at byte pos) into l; *skipped when it holds no vectors
 * Gradus can represent (points, arcs: not in a CLI either). */
static int add_block(const gr_ovf_file *f, const OpenVectorFormat__VectorBlock *vb, int64_t pos, gr_layer *l,
                     double **xy, size_t *cap, int *skipped, gr_err *e) {
  const float *p;
  size_t nf;
  int seg = vb->vector_data_case == OPEN_VECTOR_FORMAT__VECTOR_BLOCK__VECTOR_DATA__HATCHES;
  *skipped = 0;
  if (seg) { p = vb->_hatches->points; nf = vb->_hatches->n_points; }
  else if (vb->vector_data_case == OPEN_VECTOR_FORMAT__VECTOR_BLOCK__VECTOR_DATA_LINE_SEQUENCE) {
    p = vb->line_sequence->points; nf = vb->line_sequence->n_points;
  } else { *skipped = 1; return GR_OK; }
  if (nf % (seg ? 4 : 2))
    return gr_fail(e, GR_EPARSE, "%s: byte %lld: %s of %zu coordinates (a multiple of %d expected)", f->name, (long long)pos,
                   seg ? "hatches" : "line sequence", nf, seg ? 4 : 2);
  if (vb->laser_index < 0 || vb->laser_index > 1 << 20)
    return gr_fail(e, GR_EPARSE, "%s: byte %lld: laser_index %d", f->name, (long long)pos, vb->laser_index);
  size_t n = nf / 2;
  if (gr_grow(xy, cap, n + 1, 2 * sizeof(double))) return gr_fail(e, GR_EMEM, "out of memory");
  for (size_t q = 0; q < nf; q++) {
    (*xy)[q] = p[q];
    if (!isfinite((*xy)[q])) return gr_fail(e, GR_EPARSE, "%s: byte %lld: coordinate %zu is not a number", f->name, (long long)pos, q + 1);
  }
  int lp = vb->process_meta_data_case == OPEN_VECTOR_FORMAT__VECTOR_BLOCK__PROCESS_META_DATA_LPBF_METADATA && vb->lpbf_metadata;
  int area = lp ? (int)vb->lpbf_metadata->part_area : seg ? 0 : 1;
  int kind = area == OPEN_VECTOR_FORMAT__VECTOR_BLOCK__PART_AREA__CONTOUR ? GR_CONTOUR
             : area == OPEN_VECTOR_FORMAT__VECTOR_BLOCK__PART_AREA__TRANSITION_CONTOUR ? GR_EDGE : GR_HATCH;
  int shape = GR_SEGMENTS, dir = 2;
  if (!seg) {
    int closed = n >= 3 && p[0] == p[nf - 2] && p[1] == p[nf - 1];
    shape = closed ? GR_CLOSED : GR_OPEN;
    dir = closed ? (ring_area(p, n) > 0 ? 1 : 0) : 2;
    if (!closed && lp && vb->lpbf_metadata->structure_type == OPEN_VECTOR_FORMAT__VECTOR_BLOCK__STRUCTURE_TYPE__WIRESTRUCTURE)
      dir = GR_DIR_THIN;
  }
  if (gr_layer_add(l, shape, kind, vb->laser_index, dir, *xy, n)) return gr_fail(e, GR_EMEM, "out of memory");
  int skin = lp ? (int)vb->lpbf_metadata->skin_type : 0; /* regions.h: down-/up-skin */
  l->b[l->nb - 1].region = skin == OPEN_VECTOR_FORMAT__VECTOR_BLOCK__LPBFMETADATA__SKIN_TYPE__DOWN_SKIN ? GR_DOWNSKIN
                           : skin == OPEN_VECTOR_FORMAT__VECTOR_BLOCK__LPBFMETADATA__SKIN_TYPE__UP_SKIN ? GR_UPSKIN : GR_CORE;
  return GR_OK;
}

static int style_of(gr_cli_header *h, int key, const gr_ovf_file *f, int64_t pos, gr_err *e) {
  for (int i = 0; i < h->nstyles; i++) if (h->style[i].id == key) return i;
  int s = gr_cli_style_index(h, key, NAN, NAN, NAN);
  if (s < 0) return gr_fail(e, GR_EPARSE, "%s: byte %lld: more than %d marking parameter keys", f->name, (long long)pos, GR_CLI_MAXSTYLES), -1;
  return s;
}

/* The blocks listed by lut into l (after the shell set its z). */
static int read_blocks(gr_ovf_file *f, const OpenVectorFormat__WorkPlaneLUT *lut, gr_layer *l, int **style,
                       size_t *cap, gr_cli_header *h, gr_err *e) {
  double *xy = NULL;
  size_t capxy = 0;
  int rc = GR_OK;
  for (size_t b = 0; b < lut->n_vectorblockspositions && rc == GR_OK; b++) {
    int64_t pos = lut->vectorblockspositions[b];
    OpenVectorFormat__VectorBlock *vb = read_msg(f, pos, &open_vector_format__vector_block__descriptor, "vector block", e);
    if (!vb) { rc = e->code; break; }
    int skipped = 0;
    rc = add_block(f, vb, pos, l, &xy, &capxy, &skipped, e);
    if (!rc && !skipped) {
      int s = style_of(h, vb->marking_params_key, f, pos, e);
      if (s < 0) rc = e->code;
      else if (gr_grow(style, cap, l->nb, sizeof **style)) rc = gr_fail(e, GR_EMEM, "out of memory");
      else (*style)[l->nb - 1] = s;
    }
    protobuf_c_message_free_unpacked(&vb->base, NULL);
  }
  free(xy);
  return rc;
}

int gr_ovf_read_plane(gr_ovf_file *f, int i, gr_layer *l, int **style, size_t *cap, gr_cli_header *h, gr_err *e) {
  if (i < 0 || i >= gr_ovf_planes(f)) return gr_fail(e, GR_EARG, "%s: no work plane %d (the file has %d)", f->name, i, gr_ovf_planes(f));
  int64_t start = f->lut->workplanepositions[i];
  if (start < 12 || (uint64_t)start > f->len - 8)
    return gr_fail(e, GR_EPARSE, "%s: byte %lld: work plane %d starts outside the file (%zu bytes)", f->name, (long long)start, i, f->len);
  OpenVectorFormat__WorkPlaneLUT *lut = read_msg(f, rd_i64(f->t + start), &open_vector_format__work_plane_lut__descriptor, "work-plane LUT", e);
  if (!lut) return e->code;
  OpenVectorFormat__WorkPlane *wp = read_msg(f, lut->workplaneshellposition, &open_vector_format__work_plane__descriptor, "work-plane shell", e);
  int rc = wp ? GR_OK : e->code;
  if (wp) {
    gr_layer_clear(l, wp->z_pos_in_mm);
    rc = read_blocks(f, lut, l, style, cap, h, e);
    protobuf_c_message_free_unpacked(&wp->base, NULL);
  }
  protobuf_c_message_free_unpacked(&lut->base, NULL);
  return rc;
}

int gr_ovf_read_mem(const char *name, const unsigned char *t, size_t len, gr_cli_header *h, gr_cli_layer_ex_fn fn,
                    void *ud, gr_err *e) {
  gr_ovf_file *f = gr_ovf_open_mem(name, t, len, e);
  if (!f) return e->code;
  gr_ovf_header(f, h);
  gr_layer *l = gr_layer_new(0);
  int *style = NULL;
  size_t cap = 0;
  int rc = l ? GR_OK : gr_fail(e, GR_EMEM, "out of memory");
  for (int i = 0; i < gr_ovf_planes(f) && rc == GR_OK; i++) {
    rc = gr_ovf_read_plane(f, i, l, &style, &cap, h, e);
    if (!rc) rc = fn(ud, l, style, h, e);
  }
  free(style);
  gr_layer_free(l);
  gr_ovf_free(f);
  return rc;
}
