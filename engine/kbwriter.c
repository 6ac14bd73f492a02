/* kbwriter.c: the knowledge base's writer thread, see kbwriter.h. */
#include "kbwriter.h"
#include <pthread.h>
#include <stdlib.h>

struct gr_kbw {
  gr_kb *kb;
  pthread_t th;
  pthread_mutex_t mu;
  pthread_cond_t cv;          /* signals the writer (work or stop) and the pushers (room) */
  gr_template *q[GR_KBW_QUEUE];
  int n;                      /* queued */
  int stop;
  int rc;                     /* the first failure, GR_OK until then */
  gr_err err;
  long stored;
};

static void free_all(gr_template **t, int n) {
  for (int i = 0; i < n; i++) gr_template_free(t[i]);
}

static void *writer(void *arg) {
  gr_kbw *w = arg;
  gr_template *b[GR_KBW_QUEUE];
  pthread_mutex_lock(&w->mu);
  for (;;) {
    while (w->n == 0 && !w->stop) pthread_cond_wait(&w->cv, &w->mu);
    if (w->n == 0) break; /* stopped with nothing left */
    int n = w->n, failed = w->rc != GR_OK;
    for (int i = 0; i < n; i++) b[i] = w->q[i];
    w->n = 0;
    pthread_cond_broadcast(&w->cv); /* room for the pushers */
    pthread_mutex_unlock(&w->mu);
    gr_err e;
    gr_err_clear(&e);
    int rc = failed ? GR_OK : gr_kb_put_many(w->kb, (const gr_template *const *)b, (size_t)n, &e);
    free_all(b, n);
    pthread_mutex_lock(&w->mu);
    if (!failed && rc == GR_OK) w->stored += n;
    if (!failed && rc != GR_OK) w->rc = rc, w->err = e;
    pthread_cond_broadcast(&w->cv);
  }
  pthread_mutex_unlock(&w->mu);
  return NULL;
}

gr_kbw *gr_kbw_start(gr_kb *kb, gr_err *e) {
  gr_kbw *w = calloc(1, sizeof *w);
  if (!w) return gr_fail(e, GR_EMEM, "out of memory"), NULL;
  w->kb = kb;
  gr_err_clear(&w->err);
  pthread_mutex_init(&w->mu, NULL);
  pthread_cond_init(&w->cv, NULL);
  if (pthread_create(&w->th, NULL, writer, w) != 0) {
    pthread_mutex_destroy(&w->mu);
    pthread_cond_destroy(&w->cv);
    free(w);
    return gr_fail(e, GR_EMEM, "cannot start the knowledge base's writer thread"), NULL;
  }
  return w;
}

int gr_kbw_push(gr_kbw *w, gr_template *t, gr_err *e) {
  pthread_mutex_lock(&w->mu);
  while (w->n == GR_KBW_QUEUE && w->rc == GR_OK) pthread_cond_wait(&w->cv, &w->mu);
  int rc = w->rc;
  if (rc == GR_OK) {
    w->q[w->n++] = t;
    t = NULL;
    pthread_cond_broadcast(&w->cv);
  } else {
    *e = w->err;
  }
  pthread_mutex_unlock(&w->mu);
  gr_template_free(t);
  return rc;
}

int gr_kbw_finish(gr_kbw *w, long *stored, gr_err *e) {
  if (!w) return GR_OK;
  pthread_mutex_lock(&w->mu);
  w->stop = 1;
  pthread_cond_broadcast(&w->cv);
  pthread_mutex_unlock(&w->mu);
  pthread_join(w->th, NULL); /* the writer ends with the queue empty */
  int rc = w->rc;
  if (rc) *e = w->err;
  if (stored) *stored = w->stored;
  pthread_mutex_destroy(&w->mu);
  pthread_cond_destroy(&w->cv);
  free(w);
  return rc;
}
