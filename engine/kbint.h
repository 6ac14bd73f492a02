/* kbint.h: what the knowledge base's files share (kb.c: the store
 * directory, kbindex.c: its index, kbrec.c: the record codec). Internal. */
#ifndef GR_KBINT_H
#define GR_KBINT_H
#include <pthread.h>
#include "kb.h"

#define GTP_MAX_PAYLOAD ((uint64_t)1 << 34) /* a record of more bytes is garbage (16 GiB) */

struct gr_kb {
  char *dir;             /* store directory, as given */
  pthread_mutex_t lock;  /* serialises writers inside one process */
};

typedef struct gr_kb_entries {
  gr_kb_entry *v;
  size_t n, cap;
} gr_kb_entries;

/* "<a>/<b>" into a new string, or NULL. */
char *gr_kb_join(const char *a, const char *b);
/* The whole file into a new buffer (*buf, *n); 0 or an errno value. */
int gr_kb_read_all(const char *path, unsigned char **buf, size_t *n);
/* Write the file through a temporary name and rename (no half-written file). */
int gr_kb_write_atomic(const char *path, const void *data, size_t n, gr_err *e);
/* A key: 64 lowercase hex digits. */
int gr_kb_valid_key(const char *k);
/* Index entries: find by key; add (or replace, by key) the entry of t stored
 * in `bytes` bytes; order by key. */
gr_kb_entry *gr_kb_entries_find(gr_kb_entries *es, const char *key);
int gr_kb_entries_set(gr_kb_entries *es, const gr_template *t, long long created, size_t bytes);
int gr_kb_entry_cmp(const void *a, const void *b);
/* The index file index.yaml: write es (sorted) / read it (0, or non-zero
 * when missing or unreadable). */
int gr_kb_index_write(gr_kb *kb, gr_kb_entries *es, gr_err *e);
int gr_kb_index_read(const gr_kb *kb, gr_kb_entries *es);
/* Encode t as a .gtp record with an explicit creation time (gr_kb_put
 * stamps unset ones). */
int gr_kb_encode_blob(const gr_template *t, long long created, unsigned char **buf, size_t *n, gr_err *e);

#endif
