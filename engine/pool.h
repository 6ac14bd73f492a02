/* pool.h: the worker pool (a primitive under the templates stage): a
 * parallel for over n items on `threads` threads.
 *
 * Takes: a function of (context, item) and the item count. Gives: every item
 * done, or the first error (the others stop taking items). Threads pull item
 * indices from a shared counter; the calling thread works too and reports
 * progress between items. */
#ifndef GR_POOL_H
#define GR_POOL_H
#include "common.h"

typedef int (*gr_pool_fn)(void *ctx, int item, gr_err *e);
/* the same type as place.h's gr_progress_fn */
typedef void (*gr_pool_progress)(void *ud, const char *stage, long done, long total);

/* Run fn(ctx, i, e) for i = 0..n-1 on up to `threads` threads (at most 64).
 * progress (may be NULL) is called on the calling thread. */
int gr_pool_for(int n, gr_pool_fn fn, void *ctx, int threads, gr_pool_progress progress, void *pud,
                const char *stage, gr_err *e);

#endif
