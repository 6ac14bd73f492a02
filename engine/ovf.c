/* ovf.c: the Open Vector Format writer of ovf.h (the reader: ovf_read.c).
 * Each work plane is encoded into one memory buffer (its int64 LUT position,
 * vector blocks, shell and LUT are then known) and written with one call;
 * nothing of earlier layers is kept but their start positions for the job
 * LUT. Messages are packed by protobuf-c. */
#include "ovf.h"
#include "ovf.pb-c.h"
#include "outbuf.h"
#include "place.h"
#include "version.h"
#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

typedef OpenVectorFormat__VectorBlock Block;

struct gr_ovf_writer {
  gr_outbuf o;         /* the file (direct I/O where possible) */
  gr_ovf_job j;
  gr_cli_style *style;  /* copy of j.style */
  char name[256];
  int in_layer;         /* appending a layer: its room is reserved */
  int64_t *planes;      /* job LUT: start of each work plane */
  size_t nplanes, capplanes;
  int64_t *bpos;        /* this layer's block positions */
  size_t capbpos;
  float *pts;
  size_t cappts;
  double *dist;         /* a block's distances between successive points */
  size_t capdist;
  int *used;            /* marking_params_keys used by blocks */
  size_t nused, capused;
  double lo[2], hi[2];  /* bounds of everything written, mm */
  double volume, top;   /* mm^3, z of the last plane, mm */
};

static const char *const KIND[GR_NKINDS] = {"contour", "hatch", "edge"};

gr_ovf_writer *gr_ovf_open(const char *path, const gr_ovf_job *j, gr_err *e) {
  gr_ovf_writer *w = calloc(1, sizeof *w);
  if (!w) return gr_fail(e, GR_EMEM, "out of memory"), NULL;
  w->j = *j;
  snprintf(w->name, sizeof w->name, "%s", j->name ? j->name : "gradus");
  w->j.name = w->name;
  if (j->nstyles > 0) {
    w->style = malloc((size_t)j->nstyles * sizeof *w->style);
    if (!w->style) { free(w); return gr_fail(e, GR_EMEM, "out of memory"), NULL; }
    memcpy(w->style, j->style, (size_t)j->nstyles * sizeof *w->style);
  }
  w->j.style = w->style;
  w->lo[0] = w->lo[1] = INFINITY;
  w->hi[0] = w->hi[1] = -INFINITY;
  if (gr_outbuf_open(&w->o, path, 0, 4 << 20, e)) { free(w->style); free(w); return NULL; }
  unsigned char head[12] = {'L', 'V', 'F', '!'}; /* the job LUT position is filled in at close */
  if (gr_outbuf_put(&w->o, head, 12, e)) {
    gr_ovf_close(w, 0, NULL);
    return NULL;
  }
  return w;
}

static void put_i64(unsigned char *p, int64_t v) {
  uint64_t u = (uint64_t)v;
  for (int i = 0; i < 8; i++) p[i] = (u >> (8 * i)) & 255;
}

/* Append message m to the output as varint32 length + message. Within a
 * layer the room was reserved in advance (layer_bound), so nothing is
 * written out before the layer's int64 is filled in. */
static int append(gr_ovf_writer *w, const ProtobufCMessage *m, gr_err *e) {
  size_t k = protobuf_c_message_get_packed_size(m);
  if (k > 0x7fffffffu) return gr_fail(e, GR_EARG, "%s: an OVF message of %zu bytes is too large", w->o.a.path, k);
  if (w->o.n + k + 5 > w->o.cap) {
    if (w->in_layer) return gr_fail(e, GR_EARG, "%s: OVF layer larger than its reserved bound", w->o.a.path);
    if (gr_outbuf_reserve(&w->o, k + 5, e)) return e->code;
  }
  unsigned char *o = (unsigned char *)w->o.buf;
  uint32_t v = (uint32_t)k;
  do {
    o[w->o.n++] = (unsigned char)((v & 127) | (v > 127 ? 128 : 0));
    v >>= 7;
  } while (v);
  w->o.n += protobuf_c_message_pack(m, o + w->o.n);
  return GR_OK;
}

static int note_key(gr_ovf_writer *w, int key) {
  for (size_t i = 0; i < w->nused; i++) if (w->used[i] == key) return GR_OK;
  if (gr_grow(&w->used, &w->capused, w->nused + 1, sizeof *w->used)) return GR_EMEM;
  w->used[w->nused++] = key;
  return GR_OK;
}

/* What a work plane's shell says about its blocks, gathered while encoding. */
typedef struct plane_acc {
  double lo[2], hi[2]; /* bounds, mm */
  double scan, jump;   /* scan and jump (laser off, in block order) length, mm */
  double px, py;       /* where the last vector ended */
  int have;
} plane_acc;

/* Sum of d[0], d[step], d[2 step], ... below n, in four running sums (the
 * additions need not wait for one another). */
static double sum_every(const double *d, size_t n, size_t step) {
  double s[4] = {0, 0, 0, 0};
  size_t k = 0;
  for (; k + 3 * step < n; k += 4 * step) {
    s[0] += d[k];
    s[1] += d[k + step];
    s[2] += d[k + 2 * step];
    s[3] += d[k + 3 * step];
  }
  for (; k < n; k += step) s[0] += d[k];
  return (s[0] + s[1]) + (s[2] + s[3]);
}

/* Points of block b as floats into w->pts, its bounds, lengths and jumps
 * into a (polylines: a jump to the first point, segments: a jump to each
 * start). The distances between successive points are taken in a loop of
 * their own, which the compiler turns into vector square roots (one at a
 * time, their latency had been most of the OVF writer's time). */
static void convert_block(gr_ovf_writer *w, const gr_layer *l, const gr_block *b, plane_acc *a) {
  const double *p = l->xy + 2 * b->start;
  size_t n = b->n;
  double lo0 = a->lo[0], lo1 = a->lo[1], hi0 = a->hi[0], hi1 = a->hi[1];
  float *f = w->pts;
  for (size_t q = 0; q < n; q++) {
    double x = p[2 * q], y = p[2 * q + 1];
    f[2 * q] = (float)x;
    f[2 * q + 1] = (float)y;
    lo0 = x < lo0 ? x : lo0;
    hi0 = x > hi0 ? x : hi0;
    lo1 = y < lo1 ? y : lo1;
    hi1 = y > hi1 ? y : hi1;
  }
  double *d = w->dist; /* d[q - 1]: from point q - 1 to point q */
  for (size_t q = 1; q < n; q++) d[q - 1] = gr_len2d(p[2 * q] - p[2 * q - 2], p[2 * q + 1] - p[2 * q - 1]);
  double lead = n && a->have ? gr_len2d(p[0] - a->px, p[1] - a->py) : 0;
  if (b->shape == GR_SEGMENTS) { /* d[even]: vectors, d[odd]: jumps between them */
    a->scan += sum_every(d, n ? n - 1 : 0, 2);
    a->jump += lead + (n > 2 ? sum_every(d + 1, n - 2, 2) : 0);
  } else {
    a->scan += sum_every(d, n ? n - 1 : 0, 1);
    a->jump += lead;
  }
  a->lo[0] = lo0; a->lo[1] = lo1; a->hi[0] = hi0; a->hi[1] = hi1;
  if (n) {
    a->px = p[2 * n - 2];
    a->py = p[2 * n - 1];
    a->have = 1;
  }
}

/* Encode block b of l with marking_params_key `key`. */
static int put_block(gr_ovf_writer *w, const gr_layer *l, const gr_block *b, int key, plane_acc *a, gr_err *e) {
  size_t nf = 2 * b->n;
  if (gr_grow(&w->pts, &w->cappts, nf + 1, sizeof *w->pts) || gr_grow(&w->dist, &w->capdist, b->n + 1, sizeof *w->dist) ||
      note_key(w, key))
    return gr_fail(e, GR_EMEM, "out of memory");
  convert_block(w, l, b, a);
  OpenVectorFormat__VectorBlock__LineSequence ls = OPEN_VECTOR_FORMAT__VECTOR_BLOCK__LINE_SEQUENCE__INIT;
  OpenVectorFormat__VectorBlock__Hatches ht = OPEN_VECTOR_FORMAT__VECTOR_BLOCK__HATCHES__INIT;
  OpenVectorFormat__VectorBlock__VectorBlockMetaData md = OPEN_VECTOR_FORMAT__VECTOR_BLOCK__VECTOR_BLOCK_META_DATA__INIT;
  OpenVectorFormat__VectorBlock__LPBFMetadata lp = OPEN_VECTOR_FORMAT__VECTOR_BLOCK__LPBFMETADATA__INIT;
  Block vb = OPEN_VECTOR_FORMAT__VECTOR_BLOCK__INIT;
  if (b->shape == GR_SEGMENTS) {
    ht.n_points = nf;
    ht.points = w->pts;
    vb.vector_data_case = OPEN_VECTOR_FORMAT__VECTOR_BLOCK__VECTOR_DATA__HATCHES;
    vb._hatches = &ht;
  } else {
    ls.n_points = nf;
    ls.points = w->pts;
    vb.vector_data_case = OPEN_VECTOR_FORMAT__VECTOR_BLOCK__VECTOR_DATA_LINE_SEQUENCE;
    vb.line_sequence = &ls;
  }
  vb.marking_params_key = key;
  vb.laser_index = b->laser;
  md.part_key = 1;
  vb.meta_data = &md;
  lp.part_area = b->kind == GR_CONTOUR ? OPEN_VECTOR_FORMAT__VECTOR_BLOCK__PART_AREA__CONTOUR
                 : b->kind == GR_EDGE  ? OPEN_VECTOR_FORMAT__VECTOR_BLOCK__PART_AREA__TRANSITION_CONTOUR
                                       : OPEN_VECTOR_FORMAT__VECTOR_BLOCK__PART_AREA__VOLUME;
  if (b->shape == GR_OPEN && b->dir == GR_DIR_THIN) lp.structure_type = OPEN_VECTOR_FORMAT__VECTOR_BLOCK__STRUCTURE_TYPE__WIRESTRUCTURE;
  if (b->region == GR_DOWNSKIN) lp.skin_type = OPEN_VECTOR_FORMAT__VECTOR_BLOCK__LPBFMETADATA__SKIN_TYPE__DOWN_SKIN;
  if (b->region == GR_UPSKIN) lp.skin_type = OPEN_VECTOR_FORMAT__VECTOR_BLOCK__LPBFMETADATA__SKIN_TYPE__UP_SKIN;
  vb.process_meta_data_case = OPEN_VECTOR_FORMAT__VECTOR_BLOCK__PROCESS_META_DATA_LPBF_METADATA;
  vb.lpbf_metadata = &lp;
  return append(w, &vb.base, e);
}

static OpenVectorFormat__AxisAlignedBox2D box(const double lo[2], const double hi[2]) {
  OpenVectorFormat__AxisAlignedBox2D bx = OPEN_VECTOR_FORMAT__AXIS_ALIGNED_BOX2_D__INIT;
  if (lo[0] <= hi[0]) {
    bx.x_min = (float)lo[0]; bx.y_min = (float)lo[1];
    bx.x_max = (float)hi[0]; bx.y_max = (float)hi[1];
  }
  return bx;
}

static int64_t here(const gr_ovf_writer *w) { return (int64_t)(w->o.flushed + (long long)w->o.n); }

/* An upper bound of a layer's bytes: per block its floats and at most 128
 * bytes of length, keys, metadata; the shell; the LUT (10 bytes a position). */
static size_t layer_bound(const gr_layer *l) {
  return 8 + 256 + 8 * l->npts + 138 * l->nb;
}

/* A layer: the int64 (filled in last, still in the buffer), the blocks, the
 * shell and the LUT, encoded straight into the output buffer. */
static int encode_layer(gr_ovf_writer *w, const gr_layer *l, const int *keys, gr_err *e) {
  size_t slot = w->o.n;
  w->o.n += 8;
  plane_acc a = {{INFINITY, INFINITY}, {-INFINITY, -INFINITY}, 0, 0, 0, 0, 0};
  for (size_t b = 0; b < l->nb; b++) {
    const gr_block *bk = &l->b[b];
    w->bpos[b] = here(w);
    if (put_block(w, l, bk, keys ? keys[b] : gr_style_id(bk), &a, e)) return e->code;
  }
  for (int k = 0; k < 2; k++) {
    w->lo[k] = fmin(w->lo[k], a.lo[k]);
    w->hi[k] = fmax(w->hi[k], a.hi[k]);
  }
  OpenVectorFormat__WorkPlane__WorkPlaneMetaData md = OPEN_VECTOR_FORMAT__WORK_PLANE__WORK_PLANE_META_DATA__INIT;
  md.total_scan_distance_in_mm = a.scan;
  md.total_jump_distance_in_mm = a.jump;
  OpenVectorFormat__AxisAlignedBox2D bx = box(a.lo, a.hi);
  md.bounds = &bx;
  OpenVectorFormat__WorkPlane wp = OPEN_VECTOR_FORMAT__WORK_PLANE__INIT;
  wp.z_pos_in_mm = (float)l->z;
  wp.num_blocks = (int32_t)l->nb;
  wp.work_plane_number = (int32_t)w->nplanes;
  wp.meta_data = &md;
  OpenVectorFormat__WorkPlaneLUT lut = OPEN_VECTOR_FORMAT__WORK_PLANE_LUT__INIT;
  lut.workplaneshellposition = here(w);
  lut.n_vectorblockspositions = l->nb;
  lut.vectorblockspositions = w->bpos;
  if (append(w, &wp.base, e)) return e->code;
  int64_t lutpos = here(w);
  if (append(w, &lut.base, e)) return e->code;
  put_i64((unsigned char *)w->o.buf + slot, lutpos);
  return GR_OK;
}

int gr_ovf_write_layer(gr_ovf_writer *w, const gr_layer *l, const int *keys, gr_err *e) {
  if (gr_grow(&w->bpos, &w->capbpos, l->nb + 1, sizeof *w->bpos) ||
      gr_grow(&w->planes, &w->capplanes, w->nplanes + 1, sizeof *w->planes))
    return gr_fail(e, GR_EMEM, "out of memory");
  if (gr_outbuf_reserve(&w->o, layer_bound(l), e)) return e->code;
  int64_t start = here(w);
  w->in_layer = 1;
  int rc = encode_layer(w, l, keys, e);
  w->in_layer = 0;
  if (rc) return rc;
  w->planes[w->nplanes++] = start;
  w->top = l->z;
  return GR_OK;
}

void gr_ovf_set_volume(gr_ovf_writer *w, double mm3) { if (w) w->volume = mm3; }

static float us(double s) { return (float)(s * 1e6); }
static float f0(double v) { return isfinite(v) ? (float)v : 0.0f; } /* unknown (NaN) is written as absent */

static int described(const gr_ovf_writer *w, int key) {
  for (int i = 0; i < w->j.nstyles; i++) if (w->j.style[i].id == key) return 1;
  return 0;
}

/* The marking parameter sets: every style of the job, then every key used
 * by a block but not described (its name only). Arrays sized by the caller. */
static size_t marking_params(const gr_ovf_writer *w, OpenVectorFormat__Job__MarkingParamsMapEntry *ent,
                             OpenVectorFormat__Job__MarkingParamsMapEntry **pent, OpenVectorFormat__MarkingParams *mp,
                             char (*names)[64]) {
  size_t n = 0;
  for (size_t i = 0; i < (size_t)w->j.nstyles + w->nused; i++) {
    const gr_cli_style *s = i < (size_t)w->j.nstyles ? &w->j.style[i] : NULL;
    int key = s ? s->id : w->used[i - (size_t)w->j.nstyles];
    if (!s && described(w, key)) continue;
    OpenVectorFormat__MarkingParams m = OPEN_VECTOR_FORMAT__MARKING_PARAMS__INIT;
    if (s) {
      m.laser_power_in_w = f0(s->power);
      m.laser_speed_in_mm_per_s = f0(s->speed);
      m.laser_focus_shift_in_mm = f0(s->focus);
      m.jump_speed_in_mm_s = f0(s->jump_speed);
      m.jump_delay_in_us = us(w->j.jump_delay);
      m.polygon_delay_in_us = us(w->j.polygon_delay);
      snprintf(names[n], 64, "%s", s->name);
    } else {
      snprintf(names[n], 64, "laser%d-%s", key >= 1 ? (key - 1) / 3 + 1 : 1, KIND[key >= 1 ? (key - 1) % 3 : GR_EDGE]);
    }
    m.name = names[n];
    mp[n] = m;
    OpenVectorFormat__Job__MarkingParamsMapEntry en = OPEN_VECTOR_FORMAT__JOB__MARKING_PARAMS_MAP_ENTRY__INIT;
    en.key = key;
    en.value = &mp[n];
    ent[n] = en;
    pent[n] = &ent[n];
    n++;
  }
  return n;
}

/* The job shell (no work planes) and the job LUT, appended to buf. */
static int job_tail(gr_ovf_writer *w, gr_err *e) {
  size_t cap = (size_t)w->j.nstyles + w->nused + 1;
  OpenVectorFormat__Job__MarkingParamsMapEntry *ent = calloc(cap, sizeof *ent), **pent = calloc(cap, sizeof *pent);
  OpenVectorFormat__MarkingParams *mp = calloc(cap, sizeof *mp);
  char(*names)[64] = calloc(cap, 64);
  if (!ent || !pent || !mp || !names) { free(ent); free(pent); free(mp); free(names); return gr_fail(e, GR_EMEM, "out of memory"); }
  OpenVectorFormat__Job job = OPEN_VECTOR_FORMAT__JOB__INIT;
  job.n_marking_params_map = marking_params(w, ent, pent, mp, names);
  job.marking_params_map = pent;
  OpenVectorFormat__Job__JobMetaData meta = OPEN_VECTOR_FORMAT__JOB__JOB_META_DATA__INIT;
  meta.job_creation_time = (int64_t)time(NULL);
  meta.version = 1;
  meta.job_name = w->name;
  meta.author = (char *)"Gradus " GRADUS_VERSION;
  OpenVectorFormat__AxisAlignedBox2D bx = box(w->lo, w->hi);
  meta.bounds = &bx;
  job.job_meta_data = &meta;
  OpenVectorFormat__Part__ProcessStrategy ps = OPEN_VECTOR_FORMAT__PART__PROCESS_STRATEGY__INIT;
  ps.rot_angle_in_deg = (float)w->j.angle;
  ps.increment_angle_in_deg = (float)w->j.rotation;
  ps.layer_thickness_in_mm = (float)w->j.layer;
  ps.hatch_distance_in_mm = (float)w->j.hatch;
  ps.hatch_contour_distance_in_mm = (float)w->j.hatch;
  ps.contour_offset_in_mm = (float)w->j.beam_offset;
  ps.number_of_contours = w->j.contours;
  ps.contour_distance_in_mm = (float)w->j.hatch;
  ps.hatching_pattern = w->j.pattern == GR_PATTERN_ISLAND ? OPEN_VECTOR_FORMAT__PART__PROCESS_STRATEGY__HATCHING_PATTERN__CHECKERBOARD
                        : w->j.pattern == GR_PATTERN_ZIGZAG ? OPEN_VECTOR_FORMAT__PART__PROCESS_STRATEGY__HATCHING_PATTERN__BIDIRECTIONAL
                                                             : OPEN_VECTOR_FORMAT__PART__PROCESS_STRATEGY__HATCHING_PATTERN__UNIDIRECTIONAL;
  ps.name = (char *)"gradus";
  OpenVectorFormat__Part__GeometryInfo gi = OPEN_VECTOR_FORMAT__PART__GEOMETRY_INFO__INIT;
  gi.volume_in_mm3 = w->volume;
  gi.build_height_in_mm = w->top;
  OpenVectorFormat__Part part = OPEN_VECTOR_FORMAT__PART__INIT;
  part.name = w->name;
  part.geometry_info = &gi;
  part.process_strategy = &ps;
  OpenVectorFormat__Job__PartsMapEntry pe = OPEN_VECTOR_FORMAT__JOB__PARTS_MAP_ENTRY__INIT, *ppe = &pe;
  pe.key = 1;
  pe.value = &part;
  job.n_parts_map = 1;
  job.parts_map = &ppe;
  job.num_work_planes = (int32_t)w->nplanes;
  OpenVectorFormat__JobLUT lut = OPEN_VECTOR_FORMAT__JOB_LUT__INIT;
  lut.jobshellposition = here(w);
  lut.n_workplanepositions = w->nplanes;
  lut.workplanepositions = w->planes;
  int rc = append(w, &job.base, e);
  int64_t lutpos = here(w);
  if (!rc) rc = append(w, &lut.base, e);
  free(ent); free(pent); free(mp); free(names);
  if (rc) return rc;
  unsigned char p8[8];
  put_i64(p8, lutpos);
  if (gr_outbuf_flush(&w->o, e)) return e->code;
  return gr_outbuf_pwrite(&w->o, p8, 8, 4, e);
}

int gr_ovf_close(gr_ovf_writer *w, int commit, gr_err *e) {
  if (!w) return GR_OK;
  int rc = commit ? job_tail(w, e) : GR_OK;
  int crc = gr_outbuf_close(&w->o, commit && !rc, e);
  if (!rc) rc = crc;
  free(w->style);
  free(w->planes);
  free(w->bpos);
  free(w->pts);
  free(w->dist);
  free(w->used);
  free(w);
  return rc;
}
