/* kb.c: the knowledge base of toolpath templates, see kb.h and doc/kb.md. */
#include "kb.h"
#include "kbint.h"
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <pthread.h>
#include <signal.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

/* ================================================================= files */

const char *gr_kb_dir(const gr_kb *kb) { return kb->dir; }

int gr_kb_stale(const char *signature) {
  static const char any[] = "{gradus_template: ";
  return signature && !strncmp(signature, any, strlen(any)) &&
         strncmp(signature, GR_TEMPLATE_GEOMETRY, strlen(GR_TEMPLATE_GEOMETRY)) != 0;
}

/* "<a>/<b>" into a new string, or NULL. */
char *gr_kb_join(const char *a, const char *b) {
  size_t na = strlen(a), nb = strlen(b);
  char *s = malloc(na + nb + 2);
  if (!s) return NULL;
  memcpy(s, a, na);
  s[na] = '/';
  memcpy(s + na + 1, b, nb + 1);
  return s;
}

static int mkdir_p(const char *path, gr_err *e) {
  char *p = strdup(path);
  if (!p) return gr_fail(e, GR_EMEM, "out of memory");
  for (char *c = p + 1;; c++) {
    if (*c == '/' || *c == 0) {
      char save = *c;
      *c = 0;
      if (mkdir(p, 0755) != 0 && errno != EEXIST) {
        int err = errno;
        gr_fail(e, GR_EIO, "cannot create directory %s: %s", p, strerror(err));
        free(p);
        return GR_EIO;
      }
      *c = save;
      if (!save) break;
    }
  }
  struct stat st;
  int ok = stat(p, &st) == 0 && S_ISDIR(st.st_mode);
  free(p);
  if (!ok) return gr_fail(e, GR_EIO, "knowledge base path %s is not a directory", path);
  return GR_OK;
}

/* Whole file into a new buffer. Returns 0, or an errno value. */
int gr_kb_read_all(const char *path, unsigned char **buf, size_t *n) {
  *buf = NULL;
  *n = 0;
  int fd = open(path, O_RDONLY | O_CLOEXEC);
  if (fd < 0) return errno;
  struct stat st;
  if (fstat(fd, &st) != 0) { int err = errno; close(fd); return err; }
  if (!S_ISREG(st.st_mode)) { close(fd); return EISDIR; }
  if ((uint64_t)st.st_size > GTP_MAX_PAYLOAD) { close(fd); return EFBIG; }
  size_t cap = (size_t)st.st_size, len = 0;
  unsigned char *p = malloc(cap + 1);
  if (!p) { close(fd); return ENOMEM; }
  for (;;) {
    if (len == cap) { /* the file grew: read on */
      if (gr_grow(&p, &cap, cap + 4096, 1)) { free(p); close(fd); return ENOMEM; }
    }
    ssize_t k = read(fd, p + len, cap - len);
    if (k < 0 && errno == EINTR) continue;
    if (k < 0) { int err = errno; free(p); close(fd); return err; }
    if (k == 0) break;
    len += (size_t)k;
  }
  close(fd);
  if (gr_grow(&p, &cap, len + 1, 1)) { free(p); return ENOMEM; } /* spare byte for a NUL */
  *buf = p;
  *n = len;
  return 0;
}

/* Write data to `path` atomically: a unique temporary "<path>.tmp-PID-XXXXXX"
 * in the same directory (the writer's process id lets a later job tell a
 * dead writer's leftover from a live one), fsync, rename. On failure the
 * temporary is removed. */
int gr_kb_write_atomic(const char *path, const void *data, size_t n, gr_err *e) {
  size_t np = strlen(path);
  char *tmp = malloc(np + 40);
  if (!tmp) return gr_fail(e, GR_EMEM, "out of memory");
  snprintf(tmp, np + 40, "%s.tmp-%ld-XXXXXX", path, (long)getpid());
  int fd = mkstemp(tmp);
  if (fd < 0) {
    int err = errno;
    free(tmp);
    return gr_fail(e, GR_EIO, "cannot write %s: %s", path, strerror(err));
  }
  int err = 0;
  if (fchmod(fd, 0644) != 0) err = errno;
  const unsigned char *p = data;
  size_t done = 0;
  while (!err && done < n) {
    ssize_t k = write(fd, p + done, n - done);
    if (k < 0 && errno == EINTR) continue;
    if (k < 0) err = errno;
    else done += (size_t)k;
  }
  if (!err && fsync(fd) != 0) err = errno;
  if (close(fd) != 0 && !err) err = errno;
  if (!err && rename(tmp, path) != 0) err = errno;
  if (err) unlink(tmp);
  free(tmp);
  if (err) return gr_fail(e, GR_EIO, "cannot write %s: %s", path, strerror(err));
  return GR_OK;
}

/* Take the writer lock: the in-process mutex, then flock on <dir>/lock.
 * Returns the lock file descriptor (>= 0) or -1 with e filled. */
static int lock_take(gr_kb *kb, gr_err *e) {
  pthread_mutex_lock(&kb->lock);
  char *p = gr_kb_join(kb->dir, "lock");
  int fd = p ? open(p, O_RDWR | O_CREAT | O_CLOEXEC, 0644) : -1;
  int err = p ? errno : ENOMEM;
  while (fd >= 0 && flock(fd, LOCK_EX) != 0) {
    if (errno == EINTR) continue;
    err = errno;
    close(fd);
    fd = -1;
  }
  if (fd < 0) {
    gr_fail(e, GR_EIO, "cannot lock %s/lock: %s", kb->dir, strerror(err));
    pthread_mutex_unlock(&kb->lock);
  }
  free(p);
  return fd;
}

static void lock_drop(gr_kb *kb, int fd) {
  close(fd); /* releases the flock */
  pthread_mutex_unlock(&kb->lock);
}

int gr_kb_default_dir(char *out, size_t n) {
  const char *base, *suffix;
  if ((base = getenv("GRADUS_CACHE_DIR")) && *base) suffix = "/kb";
  else if ((base = getenv("XDG_CACHE_HOME")) && *base) suffix = "/gradus/kb";
  else if ((base = getenv("HOME")) && *base) suffix = "/.cache/gradus/kb";
  else return GR_EARG;
  int k = snprintf(out, n, "%s%s", base, suffix);
  return (k < 0 || (size_t)k >= n) ? GR_EARG : GR_OK;
}

gr_kb *gr_kb_open(const char *dir, gr_err *e) {
  if (!dir || !*dir) { gr_fail(e, GR_EARG, "knowledge base directory is empty"); return NULL; }
  gr_kb *kb = calloc(1, sizeof *kb);
  char *t = NULL, *lk = NULL;
  if (!kb || !(kb->dir = strdup(dir)) || !(t = gr_kb_join(dir, "t")) || !(lk = gr_kb_join(dir, "lock"))) {
    gr_fail(e, GR_EMEM, "out of memory opening %s", dir);
    goto fail;
  }
  size_t nd = strlen(kb->dir); /* "a/b/" -> "a/b" so that joined paths look clean */
  while (nd > 1 && kb->dir[nd - 1] == '/') kb->dir[--nd] = 0;
  if (mkdir_p(t, e) != GR_OK) goto fail;
  int fd = open(lk, O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) {
    gr_fail(e, GR_EIO, "cannot create %s: %s", lk, strerror(errno));
    goto fail;
  }
  close(fd);
  if (pthread_mutex_init(&kb->lock, NULL) != 0) {
    gr_fail(e, GR_EMEM, "cannot create a mutex for %s", dir);
    goto fail;
  }
  free(t);
  free(lk);
  return kb;
fail:
  free(t);
  free(lk);
  if (kb) free(kb->dir);
  free(kb);
  return NULL;
}

void gr_kb_close(gr_kb *kb) {
  if (!kb) return;
  pthread_mutex_destroy(&kb->lock);
  free(kb->dir);
  free(kb);
}

static char *blob_path(const gr_kb *kb, const char *key) {
  size_t nd = strlen(kb->dir);
  char *s = malloc(nd + 3 + 64 + 5);
  if (s) sprintf(s, "%s/t/%s.gtp", kb->dir, key);
  return s;
}

/* Read and check one blob; `key` is the name it is stored under. Returns
 * GR_OK with *out, ENOENT-absent as GR_OK with *out NULL and *absent = 1, or
 * GR_EPARSE with the reason in e. *bytes gets the file size. */
static int load_blob(const gr_kb *kb, const char *key, gr_template **out, size_t *bytes,
                     int *absent, gr_err *e) {
  *out = NULL;
  *absent = 0;
  char *path = blob_path(kb, key);
  if (!path) return gr_fail(e, GR_EMEM, "out of memory");
  unsigned char *buf;
  size_t n;
  int err = gr_kb_read_all(path, &buf, &n);
  free(path);
  if (err == ENOENT) { *absent = 1; return GR_OK; }
  if (err == ENOMEM) return gr_fail(e, GR_EMEM, "out of memory reading template %s", key);
  if (err) return gr_fail(e, GR_EPARSE, "cannot read: %s", strerror(err));
  if (bytes) *bytes = n;
  int rc = gr_template_decode(buf, n, out, e);
  free(buf);
  if (rc == GR_OK && strcmp((*out)->key, key) != 0) {
    char other[65];
    memcpy(other, (*out)->key, 65);
    gr_template_free(*out);
    *out = NULL;
    return gr_fail(e, GR_EPARSE, "holds template %.12s..., not the one its name says", other);
  }
  return rc;
}

int gr_kb_get(gr_kb *kb, const char *key, gr_template **out, char *warning, size_t wn,
              gr_err *e) {
  *out = NULL;
  if (warning && wn) warning[0] = 0;
  if (!gr_kb_valid_key(key))
    return gr_fail(e, GR_EARG, "template key must be 64 lowercase hex digits, got '%.80s'",
                   key ? key : "(null)");
  gr_err e2;
  gr_err_clear(&e2);
  int absent;
  int rc = load_blob(kb, key, out, NULL, &absent, &e2);
  if (rc == GR_EMEM) return gr_fail(e, rc, "%s", e2.msg);
  if (rc != GR_OK) {
    if (warning && wn)
      snprintf(warning, wn, "knowledge base: %s/t/%s.gtp is damaged (%s); ignored", kb->dir, key,
               e2.msg);
    *out = NULL;
  }
  return GR_OK;
}

/* ---- directory scans ---- */
typedef struct names {
  char **v;
  size_t n, cap;
} names;

static void names_free(names *ns) {
  for (size_t i = 0; i < ns->n; i++) free(ns->v[i]);
  free(ns->v);
  ns->v = NULL;
  ns->n = ns->cap = 0;
}

static int names_cmp(const void *a, const void *b) {
  return strcmp(*(char *const *)a, *(char *const *)b);
}

/* File names in `dir` (no "." or ".."), sorted. GR_OK or GR_EIO/GR_EMEM. */
static int list_dir(const char *dir, names *ns, gr_err *e) {
  ns->v = NULL;
  ns->n = ns->cap = 0;
  DIR *d = opendir(dir);
  if (!d) return gr_fail(e, GR_EIO, "cannot read directory %s: %s", dir, strerror(errno));
  struct dirent *de;
  while ((de = readdir(d))) {
    if (!strcmp(de->d_name, ".") || !strcmp(de->d_name, "..")) continue;
    char *s = strdup(de->d_name);
    if (!s || gr_grow(&ns->v, &ns->cap, ns->n + 1, sizeof *ns->v)) {
      free(s);
      closedir(d);
      names_free(ns);
      return gr_fail(e, GR_EMEM, "out of memory listing %s", dir);
    }
    ns->v[ns->n++] = s;
  }
  closedir(d);
  if (ns->n) qsort(ns->v, ns->n, sizeof *ns->v, names_cmp);
  return GR_OK;
}

static int is_temp_name(const char *s) { return strstr(s, ".tmp-") != NULL; }

/* Whether temporary `name` may still be written: its writer's process
 * ("<file>.tmp-PID-XXXXXX") is alive. The older "<file>.tmp-XXXXXX" names
 * (no PID) come only from earlier versions or crashes: debris. */
static int temp_in_use(const char *name) {
  const char *t = strstr(name, ".tmp-") + 5;
  char *end;
  long pid = strtol(t, &end, 10);
  if (end != t && *end == '-' && pid > 0) return kill((pid_t)pid, 0) == 0 || errno == EPERM;
  return 0;
}

/* "<64 hex>.gtp" -> key in k; else 0. */
static int blob_name_key(const char *s, char k[65]) {
  size_t n = strlen(s);
  if (n != 68 || strcmp(s + 64, ".gtp") != 0) return 0;
  memcpy(k, s, 64);
  k[64] = 0;
  return gr_kb_valid_key(k);
}

static int has_suffix(const char *s, const char *suf) {
  size_t n = strlen(s), m = strlen(suf);
  return n >= m && !strcmp(s + n - m, suf);
}

typedef struct msgs {
  char *p;
  size_t n, cap;
} msgs;

static void msg_add(msgs *m, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void msg_add(msgs *m, const char *fmt, ...) {
  char b[768];
  va_list ap;
  va_start(ap, fmt);
  int k = vsnprintf(b, sizeof b, fmt, ap);
  va_end(ap);
  if (k < 0) return;
  size_t len = strlen(b);
  if (gr_grow(&m->p, &m->cap, m->n + len + 2, 1)) return;
  memcpy(m->p + m->n, b, len);
  m->n += len;
  m->p[m->n++] = '\n';
  m->p[m->n] = 0;
}

/* Called for each blob while scanning t/ (name, key or "" for a bad name,
 * the template or NULL, the defect when damaged). */
typedef void (*blob_fn)(void *ctx, const char *name, const char *key, gr_template *t,
                        size_t bytes, const char *defect);

/* Visit every *.gtp in t/, fully decoded. Temporary names are skipped. */
static int scan_blobs(gr_kb *kb, blob_fn fn, void *ctx, gr_err *e) {
  char *td = gr_kb_join(kb->dir, "t");
  if (!td) return gr_fail(e, GR_EMEM, "out of memory");
  names ns;
  int rc = list_dir(td, &ns, e);
  free(td);
  if (rc) return rc;
  for (size_t i = 0; i < ns.n && rc == GR_OK; i++) {
    const char *nm = ns.v[i];
    if (is_temp_name(nm) || !has_suffix(nm, ".gtp")) continue;
    char key[65];
    if (!blob_name_key(nm, key)) {
      fn(ctx, nm, "", NULL, 0, "file name is not <64 hex digits>.gtp");
      continue;
    }
    gr_template *t = NULL;
    size_t bytes = 0;
    int absent;
    gr_err e2;
    gr_err_clear(&e2);
    int lr = load_blob(kb, key, &t, &bytes, &absent, &e2);
    if (lr == GR_EMEM) rc = gr_fail(e, lr, "%s", e2.msg);
    else if (absent) continue; /* removed meanwhile */
    else fn(ctx, nm, key, t, bytes, lr == GR_OK ? NULL : e2.msg);
    gr_template_free(t);
  }
  names_free(&ns);
  return rc;
}

typedef struct rebuild_ctx {
  gr_kb_entries es;
  msgs *m;
  int fail;
} rebuild_ctx;

static void rebuild_fn(void *ctx, const char *name, const char *key, gr_template *t,
                       size_t bytes, const char *defect) {
  rebuild_ctx *c = ctx;
  (void)key;
  if (!t) {
    if (c->m) msg_add(c->m, "t/%s: damaged (%s); left out of the index", name, defect);
    return;
  }
  if (gr_kb_entries_set(&c->es, t, t->created, bytes)) c->fail = 1;
}

/* Rebuild the index from the blobs and write it; the lock is held. On
 * success *es holds the gr_kb_entries (caller frees). */
static int index_rebuild(gr_kb *kb, gr_kb_entries *es, msgs *m, gr_err *e) {
  rebuild_ctx c = {{NULL, 0, 0}, m, 0};
  int rc = scan_blobs(kb, rebuild_fn, &c, e);
  if (rc == GR_OK && c.fail) rc = gr_fail(e, GR_EMEM, "out of memory rebuilding the index");
  if (rc == GR_OK) rc = gr_kb_index_write(kb, &c.es, e);
  if (rc != GR_OK) {
    gr_kb_entries_free(c.es.v, c.es.n);
    return rc;
  }
  *es = c.es;
  return GR_OK;
}

/* Encode t and write its blob (atomically, fsynced); the lock is held.
 * *created and *bytes: what its index entry records. */
static int put_blob(gr_kb *kb, const gr_template *t, long long *created, size_t *bytes, gr_err *e) {
  *created = t->created ? t->created : (long long)time(NULL);
  unsigned char *buf;
  int rc = gr_kb_encode_blob(t, *created, &buf, bytes, e);
  if (rc) return rc;
  char *path = blob_path(kb, t->key);
  rc = path ? gr_kb_write_atomic(path, buf, *bytes, e) : gr_fail(e, GR_EMEM, "out of memory");
  free(buf);
  free(path);
  return rc;
}

int gr_kb_put(gr_kb *kb, const gr_template *t, gr_err *e) {
  return gr_kb_put_many(kb, &t, 1, e);
}

int gr_kb_put_many(gr_kb *kb, const gr_template *const *t, size_t n, gr_err *e) {
  if (!kb) return gr_fail(e, GR_EARG, "knowledge base is NULL");
  if (n == 0) return GR_OK;
  long long *created = malloc(n * sizeof *created);
  size_t *bytes = malloc(n * sizeof *bytes);
  if (!created || !bytes) {
    free(created);
    free(bytes);
    return gr_fail(e, GR_EMEM, "out of memory");
  }
  int fd = lock_take(kb, e), rc = fd < 0 ? GR_EIO : GR_OK;
  size_t done = 0; /* blobs written: the index lists these */
  while (rc == GR_OK && done < n && (rc = put_blob(kb, t[done], &created[done], &bytes[done], e)) == GR_OK) done++;
  if (done > 0) {
    gr_err e2;
    gr_err *ei = rc ? &e2 : e; /* a blob's failure is the error to report */
    gr_kb_entries es = {NULL, 0, 0};
    int ri;
    if (gr_kb_index_read(kb, &es) != 0) {
      ri = index_rebuild(kb, &es, NULL, ei); /* includes the blobs just written */
    } else {
      ri = GR_OK;
      for (size_t k = 0; k < done && ri == GR_OK; k++)
        if (gr_kb_entries_set(&es, t[k], created[k], bytes[k])) ri = gr_fail(ei, GR_EMEM, "out of memory");
      if (ri == GR_OK) ri = gr_kb_index_write(kb, &es, ei);
    }
    gr_kb_entries_free(es.v, es.n);
    if (rc == GR_OK) rc = ri;
  }
  if (fd >= 0) lock_drop(kb, fd);
  free(created);
  free(bytes);
  return rc;
}

/* 1 if the index lists exactly the *.gtp files of t/ with their sizes. */
static int index_matches_dir(const gr_kb *kb, const gr_kb_entries *es) {
  char *td = gr_kb_join(kb->dir, "t");
  if (!td) return 0;
  names ns;
  gr_err e2;
  int ok = list_dir(td, &ns, &e2) == GR_OK;
  size_t nblobs = 0;
  for (size_t i = 0; ok && i < ns.n; i++) {
    const char *nm = ns.v[i];
    if (is_temp_name(nm) || !has_suffix(nm, ".gtp")) continue;
    char key[65];
    if (!blob_name_key(nm, key)) continue; /* foreign names are never listed */
    nblobs++;
    const gr_kb_entry *x = NULL;
    for (size_t k = 0; k < es->n && !x; k++)
      if (!strcmp(es->v[k].key, key)) x = &es->v[k];
    struct stat st;
    char *p = gr_kb_join(td, nm);
    ok = x && p && stat(p, &st) == 0 && (uint64_t)st.st_size == (uint64_t)x->bytes;
    free(p);
  }
  if (ok) ok = nblobs == es->n;
  names_free(&ns);
  free(td);
  return ok;
}

int gr_kb_list(gr_kb *kb, gr_kb_entry **out, size_t *n, char *warning, size_t wn,
               gr_err *e) {
  *out = NULL;
  *n = 0;
  if (warning && wn) warning[0] = 0;
  gr_kb_entries es;
  if (gr_kb_index_read(kb, &es) == 0 && index_matches_dir(kb, &es)) {
    *out = es.v;
    *n = es.n;
    return GR_OK;
  }
  gr_kb_entries_free(es.v, es.n);
  int fd = lock_take(kb, e);
  if (fd < 0) return GR_EIO;
  msgs m = {0};
  int rc = index_rebuild(kb, &es, &m, e);
  lock_drop(kb, fd);
  if (warning && wn && m.n) {
    if (m.p[m.n - 1] == '\n') m.p[m.n - 1] = 0;
    snprintf(warning, wn, "%s", m.p);
  }
  free(m.p);
  if (rc) return rc;
  *out = es.v;
  *n = es.n;
  return GR_OK;
}

void gr_kb_report_clear(gr_kb_report *r) {
  if (!r) return;
  free(r->messages);
  memset(r, 0, sizeof *r);
}

/* Count (and with `remove`, delete) orphan temporaries in dir and dir/t. */
static int sweep_temps(gr_kb *kb, int remove, gr_kb_report *r, msgs *m, gr_err *e) {
  const char *subs[2] = {"", "t"};
  for (int s = 0; s < 2; s++) {
    char *d = *subs[s] ? gr_kb_join(kb->dir, subs[s]) : strdup(kb->dir);
    if (!d) return gr_fail(e, GR_EMEM, "out of memory");
    names ns;
    int rc = list_dir(d, &ns, e);
    if (rc) { free(d); return rc; }
    for (size_t i = 0; i < ns.n; i++) {
      if (!is_temp_name(ns.v[i]) || temp_in_use(ns.v[i])) continue;
      r->orphans++;
      char *p = gr_kb_join(d, ns.v[i]);
      if (remove && p && unlink(p) == 0) {
        r->removed++;
        msg_add(m, "%s%s%s: orphan temporary file removed", subs[s], *subs[s] ? "/" : "", ns.v[i]);
      } else {
        msg_add(m, "%s%s%s: orphan temporary file%s", subs[s], *subs[s] ? "/" : "", ns.v[i],
                remove ? " (cannot remove)" : "");
      }
      free(p);
    }
    names_free(&ns);
    free(d);
  }
  return GR_OK;
}

typedef struct verify_ctx {
  gr_kb_report *r;
  msgs *m;
  gr_kb_entries good;       /* blobs that passed */
  int fail;
  /* prune only */
  gr_kb *kb;
  const gr_kb_prune_opts *opts;
  int prune;
} verify_ctx;

static int in_keep(const gr_kb_prune_opts *o, const char *key) {
  for (size_t i = 0; i < o->nkeep; i++)
    if (o->keep[i] && !strcmp(o->keep[i], key)) return 1;
  return 0;
}

static void verify_fn(void *ctx, const char *name, const char *key, gr_template *t,
                      size_t bytes, const char *defect) {
  verify_ctx *c = ctx;
  const char *why = NULL;
  if (!t) {
    c->r->corrupt++;
    why = defect;
  } else if (gr_kb_stale(t->signature)) {
    if (!c->prune) msg_add(c->m, "t/%s: stale: built under an older engine geometry, never served (prune removes it)", name);
    else why = "stale: built under an older engine geometry";
  } else if (c->prune && c->opts && c->opts->older_than > 0 && t->created < c->opts->older_than) {
    why = "older than the age limit";
  } else if (c->prune && c->opts && c->opts->use_keep && !in_keep(c->opts, key)) {
    why = "not in the keep-set";
  }
  if (!why) {
    c->r->ok++;
    if (gr_kb_entries_set(&c->good, t, t->created, bytes)) c->fail = 1;
    return;
  }
  if (!c->prune) {
    msg_add(c->m, "t/%s: damaged: %s", name, why);
    return;
  }
  char *td = gr_kb_join(c->kb->dir, "t");
  char *p = td ? gr_kb_join(td, name) : NULL;
  if (p && unlink(p) == 0) {
    c->r->removed++;
    msg_add(c->m, "t/%s: removed (%s)", name, why);
  } else {
    msg_add(c->m, "t/%s: cannot remove (%s): %s", name, why, strerror(errno));
  }
  free(p);
  free(td);
}

int gr_kb_verify(gr_kb *kb, gr_kb_report *r, gr_err *e) {
  memset(r, 0, sizeof *r);
  int fd = lock_take(kb, e);
  if (fd < 0) return GR_EIO;
  msgs m = {0};
  verify_ctx c = {r, &m, {NULL, 0, 0}, 0, kb, NULL, 0};
  int rc = sweep_temps(kb, 0, r, &m, e);
  if (rc == GR_OK) rc = scan_blobs(kb, verify_fn, &c, e);
  if (rc == GR_OK && c.fail) rc = gr_fail(e, GR_EMEM, "out of memory verifying");
  if (rc == GR_OK) {
    gr_kb_entries idx;
    if (gr_kb_index_read(kb, &idx) != 0) {
      msg_add(&m, "index.yaml: missing or unreadable (it is rebuilt by the next list or put)");
    } else {
      r->index_entries = idx.n;
      int same = idx.n == c.good.n;
      if (c.good.n) qsort(c.good.v, c.good.n, sizeof *c.good.v, gr_kb_entry_cmp);
      for (size_t i = 0; same && i < idx.n; i++) { /* both sorted by key */
        same = !strcmp(idx.v[i].key, c.good.v[i].key) && idx.v[i].bytes == c.good.v[i].bytes;
      }
      r->index_ok = same;
      if (!same) msg_add(&m, "index.yaml: does not match the blobs (it is rebuilt by the next list)");
      gr_kb_entries_free(idx.v, idx.n);
    }
  }
  lock_drop(kb, fd);
  gr_kb_entries_free(c.good.v, c.good.n);
  r->messages = m.p;
  return rc;
}

int gr_kb_prune(gr_kb *kb, const gr_kb_prune_opts *opts, gr_kb_report *r, gr_err *e) {
  memset(r, 0, sizeof *r);
  int fd = lock_take(kb, e);
  if (fd < 0) return GR_EIO;
  msgs m = {0};
  verify_ctx c = {r, &m, {NULL, 0, 0}, 0, kb, opts, 1};
  int rc = sweep_temps(kb, 1, r, &m, e);
  if (rc == GR_OK) rc = scan_blobs(kb, verify_fn, &c, e);
  if (rc == GR_OK && c.fail) rc = gr_fail(e, GR_EMEM, "out of memory pruning");
  if (rc == GR_OK) rc = gr_kb_index_write(kb, &c.good, e);
  if (rc == GR_OK) {
    r->index_entries = c.good.n;
    r->index_ok = 1;
  }
  lock_drop(kb, fd);
  gr_kb_entries_free(c.good.v, c.good.n);
  r->messages = m.p;
  return rc;
}

int gr_kb_sweep(gr_kb *kb, gr_kb_report *r, gr_err *e) {
  memset(r, 0, sizeof *r);
  msgs m = {0};
  int rc = sweep_temps(kb, 1, r, &m, e);
  r->messages = m.p;
  return rc;
}
