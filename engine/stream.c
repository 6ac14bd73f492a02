/* stream.c: the layer pipeline, see stream.h. */
#include "stream.h"
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include "assemble.h"
#include "lasers.h"

typedef struct lpipe {
  gr_job *j;
  int ga, gb, next, written, S, failed;
  gr_layer **slot;
  gr_job_stats *acct; /* per slot: the layer's figures (gr_lasers_account) */
  int *ready;
  pthread_mutex_t mu;
  pthread_cond_t cv;
  gr_err err;
} lpipe;

static void *lpipe_worker(void *p_) {
  lpipe *p = p_;
  gr_asm_scratch s;
  gr_err e;
  gr_err_clear(&e);
  int ok = gr_asm_scratch_init(&s, p->j->rowlen) == GR_OK;
  for (;;) {
    pthread_mutex_lock(&p->mu);
    while (!p->failed && p->next <= p->gb && p->next - (p->ga + p->written) >= p->S)
      pthread_cond_wait(&p->cv, &p->mu);
    if (p->failed || p->next > p->gb) { pthread_mutex_unlock(&p->mu); break; }
    int g = p->next++;
    pthread_mutex_unlock(&p->mu);
    int rc = ok ? gr_asm_layer(p->j, g, &s, p->slot[g % p->S], &e) : gr_fail(&e, GR_EMEM, "out of memory");
    if (rc == GR_OK) {
      memset(&p->acct[g % p->S], 0, sizeof *p->acct);
      gr_lasers_account(&p->j->m, p->slot[g % p->S], &p->acct[g % p->S]);
    }
    pthread_mutex_lock(&p->mu);
    if (rc) {
      if (!p->failed) { p->failed = 1; p->err = e; }
    } else {
      p->ready[g % p->S] = 1;
    }
    pthread_cond_broadcast(&p->cv);
    pthread_mutex_unlock(&p->mu);
  }
  gr_asm_scratch_free(&s);
  return NULL;
}

int gr_stream_layers(gr_job *j, int ga, int gb, const gr_job_run_opts *r, long *done, long total, gr_err *e) {
  if (gb < ga) return GR_OK;
  lpipe p;
  memset(&p, 0, sizeof p);
  p.j = j;
  p.ga = ga;
  p.gb = gb;
  p.next = ga;
  p.S = 4 * j->o.threads + 2;
  p.slot = calloc(p.S, sizeof *p.slot);
  p.ready = calloc(p.S, sizeof *p.ready);
  p.acct = calloc(p.S, sizeof *p.acct);
  if (!p.slot || !p.ready || !p.acct) {
    free(p.slot); free(p.ready); free(p.acct);
    return gr_fail(e, GR_EMEM, "out of memory");
  }
  int no_slots = 0;
  for (int i = 0; i < p.S; i++)
    if (!(p.slot[i] = gr_layer_new(0))) no_slots = 1;
  pthread_mutex_init(&p.mu, NULL);
  pthread_cond_init(&p.cv, NULL);
  int nt = j->o.threads > 64 ? 64 : j->o.threads;
  pthread_t th[64];
  int started = 0;
  if (!no_slots)
    for (int t = 0; t < nt; t++)
      if (pthread_create(&th[started], NULL, lpipe_worker, &p) == 0) started++;
  /* A worker may already have failed (with its own error, taken below)
   * before this point: only a job that could start no worker at all is
   * reported as such. Fewer threads than asked is fine. */
  int rc = GR_OK;
  if (no_slots) rc = gr_fail(e, GR_EMEM, "out of memory for the layer pipeline");
  else if (started == 0) rc = gr_fail(e, GR_EMEM, "cannot start any worker thread (the system refused all %d)", nt);
  for (int g = ga; g <= gb && rc == GR_OK; g++) {
    pthread_mutex_lock(&p.mu);
    while (!p.ready[g % p.S] && !p.failed) pthread_cond_wait(&p.cv, &p.mu);
    int failed = p.failed && !p.ready[g % p.S];
    pthread_mutex_unlock(&p.mu);
    if (failed) break;
    gr_layer *l = p.slot[g % p.S];
    gr_lasers_add(&j->st, &p.acct[g % p.S]);
    if (r->sink) rc = r->sink(r->sink_ud, g, l, e);
    pthread_mutex_lock(&p.mu);
    p.ready[g % p.S] = 0;
    p.written++;
    if (rc && !p.failed) { p.failed = 1; p.err = *e; }
    pthread_cond_broadcast(&p.cv);
    pthread_mutex_unlock(&p.mu);
    (*done)++;
    if (r->progress) r->progress(r->progress_ud, "layers", *done, total);
  }
  pthread_mutex_lock(&p.mu);
  if (rc) p.failed = 1;
  pthread_cond_broadcast(&p.cv);
  pthread_mutex_unlock(&p.mu);
  for (int t = 0; t < started; t++) pthread_join(th[t], NULL);
  if (p.failed && rc == GR_OK) { *e = p.err; rc = p.err.code ? p.err.code : GR_EARG; }
  for (int i = 0; i < p.S; i++) gr_layer_free(p.slot[i]);
  free(p.slot);
  free(p.ready);
  free(p.acct);
  pthread_mutex_destroy(&p.mu);
  pthread_cond_destroy(&p.cv);
  return rc;
}
