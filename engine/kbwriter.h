/* kbwriter.h: storing templates into the knowledge base on a thread of its
 * own, so that building and assembling go on while blobs are written and
 * fsynced.
 *
 * Takes: an open knowledge base and records (gr_template) handed over one by
 * one. Gives: every record stored, in batches: whatever has queued up while
 * the previous batch was written goes in one gr_kb_put_many (one index write
 * per batch instead of one per record). At most GR_KBW_QUEUE records wait;
 * a push beyond that waits for the writer (memory stays bounded when the
 * disk is slow). The first failure is kept: later pushes and the finish
 * return it, and nothing more is written. */
#ifndef GR_KBWRITER_H
#define GR_KBWRITER_H
#include "kb.h"

#define GR_KBW_QUEUE 8

typedef struct gr_kbw gr_kbw;

/* Start a writer on kb (which must outlive it); NULL + e on failure. */
gr_kbw *gr_kbw_start(gr_kb *kb, gr_err *e);
/* Queue t (the writer takes it and frees it); on an earlier failure t is
 * freed and that failure returned. */
int gr_kbw_push(gr_kbw *w, gr_template *t, gr_err *e);
/* Wait until every queued record is written, stop the thread and free w;
 * *stored (may be NULL) = records stored. Returns the first failure. */
int gr_kbw_finish(gr_kbw *w, long *stored, gr_err *e);

#endif
