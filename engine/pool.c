/* pool.c: the worker pool, see pool.h. */
#include "pool.h"
#include <pthread.h>
#include <string.h>

typedef struct pfor {
  int n, next, failed;
  gr_pool_fn fn;
  void *ctx;
  pthread_mutex_t mu;
  gr_err err;
  gr_pool_progress progress;
  void *pud;
  const char *stage;
  int done;
} pfor;

static void *pfor_main(void *p_) {
  pfor *p = p_;
  gr_err e;
  gr_err_clear(&e);
  for (;;) {
    pthread_mutex_lock(&p->mu);
    int it = p->failed ? p->n : p->next++;
    pthread_mutex_unlock(&p->mu);
    if (it >= p->n) break;
    int rc = p->fn(p->ctx, it, &e);
    pthread_mutex_lock(&p->mu);
    if (rc && !p->failed) { p->failed = 1; p->err = e; }
    p->done++;
    pthread_mutex_unlock(&p->mu);
  }
  return NULL;
}

int gr_pool_for(int n, gr_pool_fn fn, void *ctx, int threads, gr_pool_progress progress, void *pud,
                const char *stage, gr_err *e) {
  pfor p;
  memset(&p, 0, sizeof p);
  p.n = n;
  p.fn = fn;
  p.ctx = ctx;
  pthread_mutex_init(&p.mu, NULL);
  pthread_t th[64];
  int nt = threads > 64 ? 64 : threads;
  if (nt > n) nt = n;
  int started = 0;
  for (int t = 1; t < nt; t++)
    if (pthread_create(&th[started], NULL, pfor_main, &p) == 0) started++;
  /* the calling thread works too, and reports progress between items */
  for (;;) {
    pthread_mutex_lock(&p.mu);
    int it = p.failed ? p.n : p.next++;
    pthread_mutex_unlock(&p.mu);
    if (it >= p.n) break;
    gr_err le;
    gr_err_clear(&le);
    int rc = fn(ctx, it, &le);
    pthread_mutex_lock(&p.mu);
    if (rc && !p.failed) { p.failed = 1; p.err = le; }
    p.done++;
    int d = p.done;
    pthread_mutex_unlock(&p.mu);
    if (progress) progress(pud, stage, d, n);
  }
  for (int t = 0; t < started; t++) pthread_join(th[t], NULL);
  pthread_mutex_destroy(&p.mu);
  if (progress) progress(pud, stage, n, n);
  if (p.failed) {
    if (e) *e = p.err;
    return p.err.code ? p.err.code : GR_EARG;
  }
  return GR_OK;
}
