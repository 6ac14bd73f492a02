/* kb.h: the persistent knowledge base of toolpath templates (paper s.3.1,
 * 3.4; DESIGN.md "KB").
 *
 * A template holds what is computed once per unique graded voxel class: for
 * each local layer a few ring sets (e.g. slot 0 section, slot 1 contour loops,
 * slot 2 hatch region) and optionally one layer of prebuilt scans, in
 * cell-local coordinates, plus a signature, quality figures and provenance.
 *
 * The store is a directory: t/<key>.gtp (one checksummed binary blob per
 * template, authoritative), index.yaml (a cache rebuilt from the blobs when
 * missing or damaged) and a `lock` file for flock. Every write goes through a
 * temporary file in the same directory and a rename, under the lock, so two
 * processes or a crash never leave a half-written file in place. Readers never
 * trust a file: a damaged blob is reported as a warning and treated as absent.
 * The format is described byte by byte in doc/kb.md.
 *
 * Thread safety: gr_kb_get may be called from several threads at once on one
 * gr_kb (reads touch no shared mutable state). gr_kb_put(_many), gr_kb_list,
 * gr_kb_verify and gr_kb_prune serialise themselves (a mutex in gr_kb plus
 * flock across processes). */
#ifndef GR_KB_H
#define GR_KB_H
#include "common.h"
#include "paths.h"
#include <nettle/sha2.h>

/* ---- SHA-256 (FIPS 180-4), computed by nettle ---- */
typedef struct gr_sha256 {
  struct sha256_ctx ctx; /* nettle's state */
} gr_sha256;
void gr_sha256_init(gr_sha256 *s);
void gr_sha256_update(gr_sha256 *s, const void *data, size_t n);
void gr_sha256_final(gr_sha256 *s, unsigned char out[32]);
/* One-shot digest as 64 lowercase hex characters plus NUL. */
void gr_sha256_hex(const void *data, size_t n, char out[65]);

/* ---- templates ---- */
/* How every signature of the current engine geometry begins: the template
 * format and the grading rule (voxel-owned u, v, w); 3 since the nearer-patch
 * check of closest points and the widened chord brackets, 4 since in-plane
 * offsets are refined by Newton and closest-point refinements that do not
 * settle end on the surface (2026-11-25), 5 since sections look for parts of
 * the boundary narrower than the grid, chords follow cut-off tips towards
 * their neighbours' corner and in-plane distances take their sign by the
 * even-odd rule (2026-11-25), 6 since in-plane offsets find strips narrower
 * than their grid (walls just over 2b wide) and sections evaluated through
 * shared closest points take the nearest of the four nodes' patches
 * (2026-11-25), 7 since chord points found beyond the window go onto its
 * border and nesting compares boxes to 1e-9 mm (a pore bulging out of the
 * window had been taken for solid, 2026-11-25), 8 since closest-point
 * Newton steps stop at the error their convergence rate predicts (below
 * 1e-7 L; contours move by nanometres, hatch ends by up to 0.8 um where a
 * hatch line grazes the region's border, 2026-11-25), 9 since crossings and
 * chords come from the table's predicted closest points (2026-11-25), 10
 * since a closest-point refinement that overshoots (the surface curving away
 * from the point more sharply than 1/d) takes its move back and halves it
 * (contours move by up to 0.1 um on thick iwp sheets, 2026-11-27), 11 since
 * tips of slivers narrower than the chords are followed along the field's
 * crest to their end (2026-11-27), 12 since the local reach is tabled at
 * the surface's vertex spacing and model points that do not settle are
 * solved from their prediction (thick sheets' contours move by 0.3 nm,
 * hatch ends by up to 0.13 um, 2026-11-28), 13 since a crossing ends after
 * one evaluation where its Newton step's error bound allows and graded
 * sheets' slopes include T's (contours move by up to 0.19 um where a chord
 * check decides otherwise, 2026-11-28), 14 since points whose projections
 * settle slowly finish by Newton's method on their own patch (thick sheets'
 * contours move by up to 0.11 um, hatch ends by up to 0.17 um, 2026-11-29),
 * 15 since that Newton finish stops at the projections' own tolerance (a
 * foot within 1e-6 L: contours move by 0.4 nm, 2026-11-29), 16 since
 * every in-plane offset refines its chords to 0.5 um (contours had cut the
 * offset's arcs around the section's corners by up to 3.3 um between their
 * exact vertices; trimmed voxels' and face steps' offsets were refined to
 * 0.2 um, 2026-11-29), 17 since in-plane offsets are sampled first on a
 * grid of two slice cells, 18 since offsets put in the sharp corners their
 * chords cut, 19 since offsets come straight from the section's edges where
 * simple (2026-11-29), 20 since thick sheets' Newton finish starts from the
 * model's last foot and crossings whose grid line is smooth come from the
 * nodes' cubic (contours move within the chord tolerance, 2026-11-29), 21
 * since the window's cut sides move out by b (2b) and the window reaches a
 * skin's deepest contour (its margin is in the signature), 22 for a
 * narrower window, 23 since that is undone (2026-11-29), 24 since sections
 * probe inside grid cells for pores (their corners on nodes too) and the
 * narrower window is back (b + (n - 1) d, at least 2b, and two cells; face
 * steps and grid offsets treat a cut's sides as no walls, 2026-11-29), 25
 * since sections' crossings are refined to 10 nm instead of 1 nm
 * (GR_CROSS_TOL, 2026-11-30), 26 since a contour along a voxel side is
 * kept only by the voxel whose section it bounds and a clipped contour has
 * no repeated points (gr_clip_ring_owned, 2026-11-30).
 * A template whose
 * signature begins otherwise was built under an older rule: its key is never
 * asked for again, `gradus kb list` marks it stale and prune removes it. */
#define GR_TEMPLATE_GEOMETRY "{gradus_template: 26, grading: voxel-owned,"
/* 1 when a signature is a Gradus template's of an older engine geometry
 * (it begins with "{gradus_template: " but not with GR_TEMPLATE_GEOMETRY). */
int gr_kb_stale(const char *signature);

#define GR_TEMPLATE_NQ 8
typedef struct gr_template {
  char key[65];          /* lowercase hex SHA-256 of `signature` (64 chars + NUL) */
  char *signature;       /* canonical signature text (UTF-8, e.g. one YAML flow map), owned */
  int nlayers;           /* local layers */
  int nslots;            /* ring sets per layer */
  double *z;             /* nlayers local heights, mm */
  gr_rings **rings;      /* nlayers*nslots ring sets, rings[layer*nslots + slot], cell-local mm, owned */
  gr_layer **extra;      /* nlayers prebuilt scan layers (e.g. thin-wall scans), cell-local mm, or NULL; owned */
  double quality[GR_TEMPLATE_NQ]; /* caller-defined figures (e.g. pore, overmelt, max contour deviation mm); NaN = unknown */
  int qualified;         /* 1 if it passed the qualification rules, else 0 */
  long long created;     /* creation time, Unix seconds UTC; 0 = unset (gr_kb_put fills it in) */
  char *meta;            /* free-text (YAML) provenance: version, date, parameters; owned, may be NULL */
} gr_template;

/* New template with `nlayers` z = 0, every ring set allocated and empty,
 * extra layers allocated (z = 0) if with_extra, quality all NaN, key computed
 * from `signature` (copied). Returns NULL and fills e on a bad argument
 * (nlayers < 0, nslots < 1, NULL signature) or out of memory. */
gr_template *gr_template_new(const char *signature, int nlayers, int nslots,
                             int with_extra, gr_err *e);
void gr_template_free(gr_template *t); /* NULL is fine */
/* Replace meta with a copy of `meta` (NULL clears it). */
int gr_template_set_meta(gr_template *t, const char *meta, gr_err *e);
static inline gr_rings *gr_template_rings(const gr_template *t, int layer, int slot) {
  return t->rings[(size_t)layer * (size_t)t->nslots + (size_t)slot];
}

/* Serialise the whole blob (header + payload, doc/kb.md) into a new malloc'd
 * buffer *buf of *n bytes (caller frees). Fails with GR_EARG if the key does
 * not match the signature or a field is out of range. */
int gr_template_encode(const gr_template *t, unsigned char **buf, size_t *n,
                       gr_err *e);
/* Parse and check a blob: magic, version, header size, payload length,
 * checksum, every count against the bytes left, key = SHA-256(signature).
 * Any defect gives GR_EPARSE with a message saying which check failed, and
 * *out = NULL. Never trusts the input (safe on arbitrary bytes). */
int gr_template_decode(const void *buf, size_t n, gr_template **out, gr_err *e);

/* ---- the store ---- */
typedef struct gr_kb gr_kb;

/* Directory used when none is given: $GRADUS_CACHE_DIR/kb if set and not
 * empty, else $XDG_CACHE_HOME/gradus/kb, else $HOME/.cache/gradus/kb.
 * GR_EARG when none of these is set or the path does not fit in n. */
int gr_kb_default_dir(char *out, size_t n);
/* Open (creating the directory with its parents, t/ and lock if missing).
 * NULL and e filled on failure. */
gr_kb *gr_kb_open(const char *dir, gr_err *e);
void gr_kb_close(gr_kb *kb); /* NULL is fine */
const char *gr_kb_dir(const gr_kb *kb);

/* Look a template up by key. GR_OK with *out = NULL when absent, or when the
 * blob is damaged: then `warning` (wn bytes, may be NULL) says why and the
 * caller may rebuild and put it again. warning[0] = 0 when all is well.
 * GR_EARG if key is not 64 lowercase hex digits. The caller frees *out. */
int gr_kb_get(gr_kb *kb, const char *key, gr_template **out, char *warning,
              size_t wn, gr_err *e);
/* Store t (replacing any blob of the same key) and update the index. If
 * t->created is 0 the current time is recorded. */
int gr_kb_put(gr_kb *kb, const gr_template *t, gr_err *e);
/* Store n templates under one lock: each blob as gr_kb_put does, then the
 * index once (one index write for the batch instead of one per template).
 * On a failure the blobs written before it are still indexed. */
int gr_kb_put_many(gr_kb *kb, const gr_template *const *t, size_t n, gr_err *e);

/* One index entry. */
typedef struct gr_kb_entry {
  char key[65];                   /* 64 hex digits */
  char *signature;                /* owned */
  size_t bytes;                   /* blob file size, bytes */
  int qualified;                  /* 0 or 1 */
  double quality[GR_TEMPLATE_NQ]; /* as stored */
  long long created;              /* Unix seconds UTC */
} gr_kb_entry;
/* All templates in key order, from the index; the index is rebuilt from the
 * blobs (and rewritten) when it is missing, unparsable or disagrees with the
 * blob files present. Damaged blobs found while rebuilding are left out and
 * named in `warning` (may be NULL). Free with gr_kb_entries_free. */
int gr_kb_list(gr_kb *kb, gr_kb_entry **out, size_t *n, char *warning,
               size_t wn, gr_err *e);
void gr_kb_entries_free(gr_kb_entry *v, size_t n);

/* What verify and prune found and did. */
typedef struct gr_kb_report {
  size_t ok;        /* blobs that decode and match their name */
  size_t corrupt;   /* blobs that do not */
  size_t orphans;   /* leftover temporary files seen */
  size_t removed;   /* files removed (prune only) */
  size_t index_entries; /* entries in the index afterwards */
  int index_ok;     /* verify: 1 if index.yaml parses and lists exactly the good blobs */
  char *messages;   /* one line per finding, '\n'-separated; owned, may be NULL */
} gr_kb_report;
void gr_kb_report_clear(gr_kb_report *r); /* frees messages, zeroes counts */

/* Read every blob in t/ and decode it fully; count ok / corrupt, note orphan
 * temporaries and whether the index agrees. Changes nothing. */
int gr_kb_verify(gr_kb *kb, gr_kb_report *r, gr_err *e);

typedef struct gr_kb_prune_opts {
  long long older_than;   /* remove templates created before this Unix time, s; 0 = no age limit */
  const char *const *keep; /* with use_keep: keys to keep; every other template is removed */
  size_t nkeep;           /* entries in keep */
  int use_keep;           /* 1 to apply the keep-set */
} gr_kb_prune_opts;
/* Under the lock: remove orphan temporary files, damaged blobs, and the
 * templates selected by opts (may be NULL: orphans and damaged blobs only),
 * then rewrite the index from what is left. */
int gr_kb_prune(gr_kb *kb, const gr_kb_prune_opts *opts, gr_kb_report *r,
                gr_err *e);

/* Remove the temporary files that writers which are no longer running left
 * in the knowledge base (a job killed while storing a template); live
 * writers' temporaries are kept. r->removed counts them, r->messages names
 * them. Every job calls this when it opens the knowledge base. */
int gr_kb_sweep(gr_kb *kb, gr_kb_report *r, gr_err *e);

#endif
