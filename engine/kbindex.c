/* kbindex.c: the knowledge base's index (index.yaml), see kb.h and doc/kb.md. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include "kbbuf.h"
#include "kbint.h"

/* ================================================================= index */

void gr_kb_entries_free(gr_kb_entry *v, size_t n) {
  if (!v) return;
  for (size_t i = 0; i < n; i++) free(v[i].signature);
  free(v);
}

int gr_kb_entry_cmp(const void *a, const void *b) {
  return strcmp(((const gr_kb_entry *)a)->key, ((const gr_kb_entry *)b)->key);
}

gr_kb_entry *gr_kb_entries_find(gr_kb_entries *es, const char *key) {
  for (size_t i = 0; i < es->n; i++)
    if (strcmp(es->v[i].key, key) == 0) return &es->v[i];
  return NULL;
}

/* Add (or replace, by key) an entry describing t stored in `bytes` bytes. */
int gr_kb_entries_set(gr_kb_entries *es, const gr_template *t, long long created, size_t bytes) {
  char *sig = strdup(t->signature);
  if (!sig) return GR_EMEM;
  gr_kb_entry *x = gr_kb_entries_find(es, t->key);
  if (!x) {
    if (gr_grow(&es->v, &es->cap, es->n + 1, sizeof *es->v)) { free(sig); return GR_EMEM; }
    x = &es->v[es->n++];
    memset(x, 0, sizeof *x);
    memcpy(x->key, t->key, 65);
  }
  free(x->signature);
  x->signature = sig;
  x->bytes = bytes;
  x->qualified = t->qualified;
  memcpy(x->quality, t->quality, sizeof x->quality);
  x->created = created;
  return GR_OK;
}

static void w_str(wbuf *w, const char *s) { w_bytes(w, s, strlen(s)); }

static void w_fmt_double(wbuf *w, double d) {
  char b[40];
  if (isnan(d)) strcpy(b, ".nan");
  else if (isinf(d)) strcpy(b, d > 0 ? ".inf" : "-.inf");
  else snprintf(b, sizeof b, "%.17g", d);
  w_str(w, b);
}

/* YAML double-quoted scalar: escapes for '"', '\\' and control bytes; UTF-8
 * passes through. */
static void w_quoted(wbuf *w, const char *s) {
  w_str(w, "\"");
  for (const unsigned char *c = (const unsigned char *)s; *c; c++) {
    char b[8];
    if (*c == '"') w_str(w, "\\\"");
    else if (*c == '\\') w_str(w, "\\\\");
    else if (*c == '\n') w_str(w, "\\n");
    else if (*c == '\t') w_str(w, "\\t");
    else if (*c == '\r') w_str(w, "\\r");
    else if (*c < 0x20 || *c == 0x7f) { snprintf(b, sizeof b, "\\x%02x", *c); w_str(w, b); }
    else w_bytes(w, c, 1);
  }
  w_str(w, "\"");
}

static void fmt_time(long long t, char out[32]) {
  time_t tt = (time_t)t;
  struct tm tm;
  if (!gmtime_r(&tt, &tm) || !strftime(out, 32, "%Y-%m-%dT%H:%M:%SZ", &tm))
    strcpy(out, "1970-01-01T00:00:00Z");
}

static int parse_time(const char *s, long long *t) {
  struct tm tm;
  memset(&tm, 0, sizeof tm);
  int n = 0;
  if (sscanf(s, "%4d-%2d-%2dT%2d:%2d:%2dZ%n", &tm.tm_year, &tm.tm_mon, &tm.tm_mday, &tm.tm_hour,
             &tm.tm_min, &tm.tm_sec, &n) != 6 || s[n] != 0)
    return -1;
  tm.tm_year -= 1900;
  tm.tm_mon -= 1;
  *t = (long long)timegm(&tm);
  return 0;
}

/* Write index.yaml from the gr_kb_entries (sorted first). Caller holds the lock. */
int gr_kb_index_write(gr_kb *kb, gr_kb_entries *es, gr_err *e) {
  if (es->n) qsort(es->v, es->n, sizeof *es->v, gr_kb_entry_cmp);
  wbuf w = {0};
  w_str(&w, "# Gradus knowledge base index: a cache, rebuilt from t/*.gtp when missing or damaged.\n");
  w_str(&w, "format: 1\n");
  w_str(&w, es->n ? "templates:\n" : "templates: []\n");
  for (size_t i = 0; i < es->n; i++) {
    const gr_kb_entry *x = &es->v[i];
    char b[256], tm[32];
    fmt_time(x->created, tm);
    snprintf(b, sizeof b, "  - key: %s\n    signature: ", x->key);
    w_str(&w, b);
    w_quoted(&w, x->signature);
    snprintf(b, sizeof b, "\n    file: t/%s.gtp\n    bytes: %zu\n    created: %s\n    qualified: %s\n    quality: [",
             x->key, x->bytes, tm, x->qualified ? "true" : "false");
    w_str(&w, b);
    for (int k = 0; k < GR_TEMPLATE_NQ; k++) {
      if (k) w_str(&w, ", ");
      w_fmt_double(&w, x->quality[k]);
    }
    w_str(&w, "]\n");
  }
  if (w.fail) { free(w.p); return gr_fail(e, GR_EMEM, "out of memory writing the index"); }
  char *path = gr_kb_join(kb->dir, "index.yaml");
  int rc = path ? gr_kb_write_atomic(path, w.p, w.n, e) : gr_fail(e, GR_EMEM, "out of memory");
  free(path);
  free(w.p);
  return rc;
}

/* Undo w_quoted. Returns a new string or NULL when malformed. */
static char *unquote(const char *s) {
  size_t n = strlen(s);
  if (n < 2 || s[0] != '"' || s[n - 1] != '"') return NULL;
  char *o = malloc(n), *q = o;
  if (!o) return NULL;
  for (size_t i = 1; i < n - 1; i++) {
    if (s[i] == '"') { free(o); return NULL; }
    if (s[i] != '\\') { *q++ = s[i]; continue; }
    if (++i >= n - 1) { free(o); return NULL; }
    switch (s[i]) {
      case '"': *q++ = '"'; break;
      case '\\': *q++ = '\\'; break;
      case 'n': *q++ = '\n'; break;
      case 't': *q++ = '\t'; break;
      case 'r': *q++ = '\r'; break;
      case 'x': {
        unsigned v;
        if (i + 2 >= n - 1 || sscanf(s + i + 1, "%2x", &v) != 1 || v == 0) { free(o); return NULL; }
        *q++ = (char)v;
        i += 2;
        break;
      }
      default: free(o); return NULL;
    }
  }
  *q = 0;
  return o;
}

static int parse_double(const char *s, double *d) {
  if (!strcmp(s, ".nan")) { *d = NAN; return 0; }
  if (!strcmp(s, ".inf")) { *d = INFINITY; return 0; }
  if (!strcmp(s, "-.inf")) { *d = -INFINITY; return 0; }
  char *end;
  *d = strtod(s, &end);
  return (end == s || *end) ? -1 : 0;
}

/* Parse the index as written by gr_kb_index_write. Returns 0 and fills es, or -1
 * (es emptied) when the file is missing or is not exactly that format. */
int gr_kb_index_read(const gr_kb *kb, gr_kb_entries *es) {
  es->v = NULL;
  es->n = es->cap = 0;
  char *path = gr_kb_join(kb->dir, "index.yaml");
  unsigned char *buf = NULL;
  size_t n = 0;
  int err = path ? gr_kb_read_all(path, &buf, &n) : ENOMEM;
  free(path);
  if (err) return -1;
  buf[n] = 0; /* gr_kb_read_all leaves one spare byte */
  if (memchr(buf, 0, n)) { free(buf); return -1; }
  enum { F_KEY = 1, F_SIG = 2, F_FILE = 4, F_BYTES = 8, F_CREATED = 16, F_QUAL = 32, F_QUALITY = 64, F_ALL = 127 };
  int ok = 1, seen_format = 0, seen_templates = 0, empty_list = 0, fields = F_ALL;
  gr_kb_entry *x = NULL;
  char *line = (char *)buf;
  while (ok && line && *line) {
    char *nl = strchr(line, '\n');
    if (nl) *nl = 0;
    char *next = nl ? nl + 1 : NULL;
    if (line[0] == '#' || line[0] == 0) { line = next; continue; }
    if (!strcmp(line, "format: 1")) seen_format = 1;
    else if (!strcmp(line, "templates:") && seen_format && !seen_templates) seen_templates = 1;
    else if (!strcmp(line, "templates: []") && seen_format && !seen_templates) seen_templates = empty_list = 1;
    else if (!strncmp(line, "  - key: ", 9) && seen_templates && !empty_list) {
      if (fields != F_ALL) { ok = 0; break; }
      if (!gr_kb_valid_key(line + 9) || gr_kb_entries_find(es, line + 9)) { ok = 0; break; }
      if (gr_grow(&es->v, &es->cap, es->n + 1, sizeof *es->v)) { ok = 0; break; }
      x = &es->v[es->n++];
      memset(x, 0, sizeof *x);
      memcpy(x->key, line + 9, 65);
      fields = F_KEY;
    } else if (x && !strncmp(line, "    signature: ", 15) && !(fields & F_SIG)) {
      ok = (x->signature = unquote(line + 15)) != NULL;
      fields |= F_SIG;
    } else if (x && !strncmp(line, "    file: ", 10) && !(fields & F_FILE)) {
      char want[80];
      snprintf(want, sizeof want, "t/%s.gtp", x->key);
      ok = !strcmp(line + 10, want);
      fields |= F_FILE;
    } else if (x && !strncmp(line, "    bytes: ", 11) && !(fields & F_BYTES)) {
      char *end;
      errno = 0;
      unsigned long long v = strtoull(line + 11, &end, 10);
      ok = end != line + 11 && !*end && !errno && line[11] != '-';
      x->bytes = (size_t)v;
      fields |= F_BYTES;
    } else if (x && !strncmp(line, "    created: ", 13) && !(fields & F_CREATED)) {
      ok = parse_time(line + 13, &x->created) == 0;
      fields |= F_CREATED;
    } else if (x && !strncmp(line, "    qualified: ", 15) && !(fields & F_QUAL)) {
      ok = !strcmp(line + 15, "true") || !strcmp(line + 15, "false");
      x->qualified = !strcmp(line + 15, "true");
      fields |= F_QUAL;
    } else if (x && !strncmp(line, "    quality: [", 14) && !(fields & F_QUALITY)) {
      char *s = line + 14, *end = strchr(s, ']');
      ok = end && end[1] == 0;
      if (ok) *end = 0;
      for (int k = 0; ok && k < GR_TEMPLATE_NQ; k++) {
        char *comma = strchr(s, ',');
        if ((k < GR_TEMPLATE_NQ - 1) != (comma != NULL)) { ok = 0; break; }
        if (comma) *comma = 0;
        while (*s == ' ') s++;
        ok = parse_double(s, &x->quality[k]) == 0;
        s = comma ? comma + 1 : s;
      }
      fields |= F_QUALITY;
    } else ok = 0;
    line = next;
  }
  ok = ok && seen_format && seen_templates && fields == F_ALL;
  free(buf);
  if (!ok) {
    gr_kb_entries_free(es->v, es->n);
    es->v = NULL;
    es->n = es->cap = 0;
    return -1;
  }
  if (es->n) qsort(es->v, es->n, sizeof *es->v, gr_kb_entry_cmp);
  return 0;
}

