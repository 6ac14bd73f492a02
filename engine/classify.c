/* classify.c: voxel classes and signatures, see classify.h. */
#include "classify.h"
#include "density.h"
#include "domain.h"
#include "template.h"
#include "regions.h"
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define NS 4 /* thickness samples per axis for the signature */

/* A domain without a known Lipschitz bound (an expression): a local bound
 * estimated from the gradient at the voxel's samples, with a safety factor
 * (the gradient may grow between samples); INFINITY if it cannot be had. */
#define LIP_SAFETY 1.5
static double local_lipschitz(const gr_field *d, int n, const double *x, const double *y, const double *z) {
  double gx[125], gy[125], gz[125], g = 0;
  gr_err e;
  gr_err_clear(&e);
  if (n > 125 || gr_field_grad(d, (size_t)n, x, y, z, gx, gy, gz, &e)) return INFINITY;
  for (int q = 0; q < n; q++) g = fmax(g, sqrt(gx[q] * gx[q] + gy[q] * gy[q] + gz[q] * gz[q]));
  return isfinite(g) && g > 0 ? LIP_SAFETY * g : INFINITY;
}

/* Classify voxels against the domain: sample the domain field on a 5^3
 * lattice of the voxel grown by the contour margin; all positive -> outside,
 * all negative -> inside, else cut. With a Lipschitz bound (known, or
 * estimated from the gradient for an expression) the samples also prove
 * emptiness of the gaps between them; a voxel inside is inside the skin's
 * reach only if no sample is within skin + h of the boundary, so a voxel
 * wholly inside beyond the skin is an ordinary voxel (shares templates). */
/* The cell lengths as text: "%.9g" for a cube (the signature of cubic cells
 * is unchanged), "Lx,Ly,Lz" for a stretched cell. */
typedef struct cell_txt { char s[96]; } cell_txt;
static cell_txt cell_text(const double L[3]) {
  cell_txt t;
  if (gr_cell_cube(L)) snprintf(t.s, sizeof t.s, "%.9g", L[0]);
  else snprintf(t.s, sizeof t.s, "%.9g,%.9g,%.9g", L[0], L[1], L[2]);
  return t;
}

static int classify_domain(gr_job *j, gr_err *e) {
  if (!j->domain) return GR_OK;
  double K0 = gr_field_lipschitz(j->domain);
  enum { M = 5 };
  double x[M * M * M], y[M * M * M], z[M * M * M], f[M * M * M];
  const double *Lv = j->o.cell;
  double grow = j->o.beam_offset + j->o.contours * j->o.hatch + j->skin;
  double hv[3];
  for (int a = 0; a < 3; a++) hv[a] = (Lv[a] + 2 * grow) / (M - 1);
  double h = fmax(hv[0], fmax(hv[1], hv[2]));
  double ilo[3] = {INFINITY, INFINITY, INFINITY}, ihi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (int v = 0; v < j->nvox; v++) {
    if (j->vspec[v] < 0) continue;
    double o[3];
    gr_grid_origin(&j->grid, v, o);
    int n = 0;
    for (int a = 0; a < M; a++)
      for (int b = 0; b < M; b++)
        for (int c = 0; c < M; c++, n++) {
          x[n] = o[0] - grow + a * hv[0];
          y[n] = o[1] - grow + b * hv[1];
          z[n] = o[2] - grow + c * hv[2];
        }
    if (gr_field_eval(j->domain, n, x, y, z, f, e)) return gr_err_prefix(e, "domain");
    double K = isfinite(K0) ? K0 : local_lipschitz(j->domain, n, x, y, z);
    int pos = 0, neg = 0;
    /* half the samples' diagonal (a cube: as it always was) */
    double half = gr_cell_cube(Lv) ? h * sqrt(3.0) / 2 : sqrt(hv[0] * hv[0] + hv[1] * hv[1] + hv[2] * hv[2]) / 2;
    for (int q = 0; q < n; q++) {
      double margin = isfinite(K) ? K * half : 0;
      if (f[q] > margin) pos++;
      else if (f[q] < -margin) neg++;
    }
    if (neg == n) j->vstate[v] = 1 + (j->skin > 0 ? 0 : 0);
    else if (pos == n) j->vstate[v] = 0;
    else j->vstate[v] = 2;
    if (j->skin > 0 && j->vstate[v] == 1) {
      /* a voxel within the skin's reach of the boundary is cut too */
      for (int q = 0; q < n; q++)
        if (isfinite(K) ? -f[q] / K < j->skin + h : 1) { j->vstate[v] = 2; break; }
    }
    for (int q = 0; q < n; q++)
      if (f[q] < 0) {
        double p[3] = {x[q], y[q], z[q]};
        for (int a = 0; a < 3; a++) { ilo[a] = fmin(ilo[a], p[a]); ihi[a] = fmax(ihi[a], p[a]); }
      }
  }
  /* a domain positive at every sample holds nothing of the part: refuse it */
  int any = 0, some = 0;
  for (int v = 0; v < j->nvox; v++) some |= j->vspec[v] >= 0, any |= j->vspec[v] >= 0 && j->vstate[v] != 0;
  if (some && !any)
    return gr_fail(e, GR_EARG, "the domain %s is empty inside the box of cells (positive at every sample): no part",
                   gr_field_describe(j->domain));
  /* a domain smaller than one cell along every axis holds no cell: refuse it
   * (extent from the samples inside it, one sample spacing added) */
  int small = isfinite(ilo[0]);
  for (int a = 0; a < 3 && small; a++) small = ihi[a] - ilo[a] + hv[a] < Lv[a];
  if (small)
    return gr_fail(e, GR_EARG,
                   "cell %s mm is larger than the design domain (about %.2g x %.2g x %.2g mm); choose a smaller cell",
                   cell_text(Lv).s, ihi[0] - ilo[0] + hv[0], ihi[1] - ilo[1] + hv[1], ihi[2] - ilo[2] + hv[2]);
  return GR_OK;
}

/* Signature text of voxel v: everything that changes its toolpaths. */
static char *voxel_signature(gr_job *j, int v, gr_err *e) {
  const gr_spec *s = &j->specs[j->vspec[v]];
  double o[3];
  gr_grid_origin(&j->grid, v, o);
  int i, jj, k;
  gr_grid_ijk(&j->grid, v, &i, &jj, &k);
  const double *L = j->o.cell;
  enum { N = NS * NS * NS };
  double x[N], y[N], z[N], u[N], vv[N], w[N], t[N], ti[N];
  int n = 0;
  for (int a = 0; a < NS; a++)
    for (int b = 0; b < NS; b++)
      for (int c = 0; c < NS; c++, n++) {
        double fa = (a + 0.5) / NS, fb = (b + 0.5) / NS, fc = (c + 0.5) / NS;
        x[n] = o[0] + fa * L[0];
        y[n] = o[1] + fb * L[1];
        z[n] = o[2] + fc * L[2];
        u[n] = 2 * fa - 1;
        vv[n] = 2 * fb - 1;
        w[n] = 2 * fc - 1;
      }
  const double *vars[6] = {x, y, z, u, vv, w};
  if (s->target ? gr_field_eval(s->target, N, x, y, z, t, e) : gr_expr_eval(j->texpr[j->vspec[v]], N, vars, t, e)) return NULL;
  if (j->iexpr[j->vspec[v]] && gr_expr_eval(j->iexpr[j->vspec[v]], N, vars, ti, e)) return NULL;
  for (int q = 0; q < N; q++) j->tsig = fmax(j->tsig, fmax(t[q], j->iexpr[j->vspec[v]] ? ti[q] : 0));
  size_t cap = 2048 + N * 24 * 2;
  char *sig = malloc(cap);
  if (!sig) return gr_fail(e, GR_EMEM, "out of memory"), NULL;
  int g0 = gr_grid_row_first(&j->grid, k);
  double phase = gr_grid_mid(&j->grid, g0) - o[2];
  size_t len = (size_t)snprintf(
      sig, cap,
      GR_TEMPLATE_GEOMETRY " surface: %s, L: %s, level: %.9g, kind: %s, side: %d, "
      "phase: %.9g, layers: %d, t: %.9g, d: %.9g, b: %.9g, contours: %d, cell: %.9g, window: %.9g, res: %d, "
      "mode: %s, quant: %.9g, T: [",
      gr_tpms_name(s->surface), cell_text(L).s, s->level, s->network ? "network" : "sheet", s->side,
      round(phase / 1e-9) * 1e-9, gr_grid_row_layers(&j->grid, k), j->o.layer, j->o.hatch,
      j->o.beam_offset, j->o.contours, j->o.slice_cell, gr_job_window(j), j->o.res,
      j->o.exact ? "exact" : "mesh", j->o.quant);
  for (int q = 0; q < N; q++)
    len += (size_t)snprintf(sig + len, cap - len, "%s%lld", q ? "," : "", (long long)llround(t[q] / j->o.quant));
  len += (size_t)snprintf(sig + len, cap - len, "]");
  if (s->density || s->target) /* density samples: name the table; a field: its source */
    len += (size_t)snprintf(sig + len, cap - len, ", density: \"%s\", target: \"%s\"", s->density ? gr_dtable_key(s->density) : "",
                            s->target ? gr_field_describe(s->target) : "");
  if (j->iexpr[j->vspec[v]]) {
    len += (size_t)snprintf(sig + len, cap - len, ", Tin: [");
    for (int q = 0; q < N; q++)
      len += (size_t)snprintf(sig + len, cap - len, "%s%lld", q ? "," : "", (long long)llround(ti[q] / j->o.quant));
    len += (size_t)snprintf(sig + len, cap - len, "]");
  }
  snprintf(sig + len, cap - len, "}");
  return sig;
}

/* The key of the domain's boundary near trimmed voxel v (domain.h): the
 * box is the template's window (gr_job_window) in x and y and the voxel in
 * z, grown by the skin and a quarter cell, beyond which only d's sign
 * matters to the trimmed value's zero set (the lattice's zero set where d <
 * -skin, none where d > 0). 1 and key, 0 (no key), -1 (error). */
static int trimmed_key(gr_job *j, int v, char key[65], gr_err *e) {
  const double *L = j->o.cell;
  double m = gr_job_window(j), D = j->skin + 0.25 * fmin(L[0], fmin(L[1], L[2]));
  double o[3], lo[3] = {-m - D, -m - D, -D}, hi[3] = {L[0] + m + D, L[1] + m + D, L[2] + D};
  gr_grid_origin(&j->grid, v, o);
  int rc = gr_domain_local_key(j->domain, lo, hi, o, key, e);
  if (rc < 0) gr_err_prefix(e, "domain");
  return rc;
}

int gr_classify_run(gr_job *j, int direct, gr_err *e) {
  if (j->nspecs == 0) return gr_fail(e, GR_EARG, "job has no cell spec");
  if (classify_domain(j, e)) return e->code;
  for (int c = 0; c < j->ncls; c++) {
    gr_tmpl_free(j->cls[c].t);
    free(j->cls[c].sig);
  }
  free(j->cls);
  j->cls = calloc(j->nvox + 1, sizeof *j->cls);
  if (!j->cls) return gr_fail(e, GR_EMEM, "out of memory");
  j->ncls = 0;
  j->tsig = 0;
  /* hash of keys -> class */
  size_t nb = 1;
  while (nb < (size_t)j->nvox * 2) nb <<= 1;
  int *head = malloc(nb * sizeof *head), *link = malloc((j->nvox + 1) * sizeof *link);
  if (!head || !link) { free(head); free(link); return gr_fail(e, GR_EMEM, "out of memory"); }
  for (size_t b = 0; b < nb; b++) head[b] = -1;
  memset(&j->st.voxels, 0, sizeof j->st.voxels);
  j->st.trimmed = j->st.trimmed_classes = 0;
  for (int v = 0; v < j->nvox; v++) {
    j->vcls[v] = -1;
    if (j->vspec[v] < 0 || j->vstate[v] == 0) continue;
    char *sig = voxel_signature(j, v, e);
    if (!sig) { free(head); free(link); return e->code; }
    char key[65];
    if (j->vstate[v] == 2 || direct) {
      char buf[160];
      int dk = j->vstate[v] == 2 && !direct ? trimmed_key(j, v, key, e) : 0;
      if (dk < 0) { free(sig); free(head); free(link); return e->code; }
      if (dk) snprintf(buf, sizeof buf, ", domain: %s, skin: %.9g, trimmed: 1", key, j->skin);
      else snprintf(buf, sizeof buf, ", voxel: %d, trimmed: %d", v, j->vstate[v] == 2);
      size_t sl = strlen(sig);
      char *s2 = realloc(sig, sl + strlen(buf) + 1);
      if (!s2) { free(sig); free(head); free(link); return gr_fail(e, GR_EMEM, "out of memory"); }
      sig = s2;
      memmove(sig + sl - 1, buf, strlen(buf) + 1);
      strcat(sig, "}");
    }
    gr_sha256_hex(sig, strlen(sig), key);
    size_t b = strtoull(key + 48, NULL, 16) & (nb - 1);
    int c = head[b];
    while (c >= 0 && strcmp(j->cls[c].key, key) != 0) c = link[c];
    if (c < 0) {
      c = j->ncls++;
      memset(&j->cls[c], 0, sizeof j->cls[c]);
      j->cls[c].rep = v;
      j->cls[c].sig = sig;
      j->cls[c].trimmed = j->vstate[v] == 2;
      j->st.trimmed_classes += j->vstate[v] == 2;
      memcpy(j->cls[c].key, key, 65);
      link[c] = head[b];
      head[b] = c;
    } else {
      free(sig);
    }
    j->cls[c].count++;
    j->vcls[v] = c;
    j->st.voxels++;
    if (j->vstate[v] == 2) j->st.trimmed++;
  }
  free(head);
  free(link);
  j->st.classes = j->ncls;
  /* the classes that meet the part's boundary: only their templates need side segments */
  for (int v = 0; v < j->nvox; v++)
    if (j->vcls[v] >= 0 && gr_voxel_sides(j, v)) j->cls[j->vcls[v]].edge = 1;
  return GR_OK;
}

int gr_voxel_sides(const gr_job *j, int v) {
  if (!j->o.faces) return 0;
  int i, jj, k, nx = j->o.n[0], ny = j->o.n[1], m = 0;
  gr_grid_ijk(&j->grid, v, &i, &jj, &k);
  if (i == 0 || j->vcls[v - 1] < 0) m |= 1;
  if (i == nx - 1 || j->vcls[v + 1] < 0) m |= 2;
  if (jj == 0 || j->vcls[v - nx] < 0) m |= 4;
  if (jj == ny - 1 || j->vcls[v + nx] < 0) m |= 8;
  return m;
}

/* ---- template build ---- */

typedef struct vkey { double key; int v; } vkey;
static int vkey_cmp(const void *a, const void *b) {
  const vkey *p = a, *q = b;
  if (p->key != q->key) return p->key < q->key ? -1 : 1;
  return p->v - q->v;
}

int gr_classify_rows(gr_job *j, gr_err *e) {
  int nx = j->o.n[0], ny = j->o.n[1], nz = j->o.n[2];
  free(j->roworder);
  free(j->rowcount);
  j->rowlen = nx * ny;
  j->roworder = malloc((size_t)j->nvox * sizeof *j->roworder);
  j->rowcount = calloc(nz, sizeof *j->rowcount);
  vkey *tmp = malloc((size_t)j->rowlen * sizeof *tmp);
  if (!j->roworder || !j->rowcount || !tmp) { free(tmp); return gr_fail(e, GR_EMEM, "out of memory"); }
  for (int k = 0; k < nz; k++) {
    int n = 0;
    for (int q = 0; q < nx * ny; q++) {
      int v = q + nx * ny * k;
      if (j->vcls[v] >= 0) tmp[n++] = (vkey){j->vseq[v], v};
    }
    qsort(tmp, n, sizeof *tmp, vkey_cmp);
    for (int q = 0; q < n; q++) j->roworder[(size_t)k * j->rowlen + q] = tmp[q].v;
    j->rowcount[k] = n;
  }
  free(tmp);
  return GR_OK;
}

