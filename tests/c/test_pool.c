/* test_pool.c: the worker pool. Every item is done exactly once; an item that
 * fails gives its own error to the caller, whichever thread ran it and however
 * the threads are scheduled (under load a worker's error was once replaced by
 * a different one: repeat the failing case many times). */
#include "check.h"
#include "pool.h"
#include <stdatomic.h>
#include <string.h>

typedef struct {
  atomic_int seen[512];
  int fail_at; /* -1: no item fails */
  long last_done, calls;
} ctx_t;

static int item_fn(void *c_, int item, gr_err *e) {
  ctx_t *c = c_;
  atomic_fetch_add(&c->seen[item], 1);
  if (item == c->fail_at) return gr_fail(e, GR_EARG, "item %d failed on purpose", item);
  return GR_OK;
}

static void progress(void *ud, const char *stage, long done, long total) {
  ctx_t *c = ud;
  (void)stage;
  if (done > total || done < c->last_done) c->last_done = -1000000;
  else c->last_done = done;
  c->calls++;
}

TEST(every_item_once) {
  for (int threads = 1; threads <= 8; threads++) {
    static ctx_t c;
    memset(&c, 0, sizeof c);
    c.fail_at = -1;
    gr_err e;
    gr_err_clear(&e);
    int rc = gr_pool_for(500, item_fn, &c, threads, progress, &c, "test", &e);
    CHECK(rc == GR_OK, "threads %d: rc %d (%s)", threads, rc, e.msg);
    int bad = 0;
    for (int i = 0; i < 500; i++) bad += atomic_load(&c.seen[i]) != 1;
    CHECK(bad == 0, "threads %d: %d items not done exactly once", threads, bad);
    CHECK(c.last_done == 500, "threads %d: progress ended at %ld of 500", threads, c.last_done);
  }
}

TEST(a_failing_item_gives_its_own_error) {
  int wrong = 0;
  for (int rep = 0; rep < 2000; rep++) {
    static ctx_t c;
    memset(&c, 0, sizeof c);
    c.fail_at = rep % 7; /* early items: the failure races the threads' start */
    gr_err e;
    gr_err_clear(&e);
    int threads = 2 + rep % 7;
    int rc = gr_pool_for(64, item_fn, &c, threads, NULL, NULL, "test", &e);
    char want[64];
    snprintf(want, sizeof want, "item %d failed on purpose", c.fail_at);
    if (rc != GR_EARG || strcmp(e.msg, want) != 0) wrong++;
  }
  CHECK(wrong == 0, "%d of 2000 runs gave another error than the failing item's", wrong);
}

TEST(more_threads_than_items) {
  static ctx_t c;
  memset(&c, 0, sizeof c);
  c.fail_at = -1;
  gr_err e;
  gr_err_clear(&e);
  CHECK(gr_pool_for(3, item_fn, &c, 64, NULL, NULL, "test", &e) == GR_OK, "%s", e.msg);
  CHECK(atomic_load(&c.seen[0]) + atomic_load(&c.seen[1]) + atomic_load(&c.seen[2]) == 3, "3 items done");
  CHECK(gr_pool_for(0, item_fn, &c, 4, NULL, NULL, "test", &e) == GR_OK, "no items is fine");
}

int main(void) {
  RUN(every_item_once);
  RUN(a_failing_item_gives_its_own_error);
  RUN(more_threads_than_items);
  DONE();
}
