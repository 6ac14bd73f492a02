/* stream.h: the layer pipeline: the part's layers placed in parallel and
 * handed over in order.
 *
 * Takes: the job with its templates and a layer range ga..gb. Gives: every
 * layer to the run's sink (the CLI writer) in order, on the calling thread,
 * and its figures (lasers.h) added to the job's statistics in layer order.
 * Workers place layers (assemble.h), each with its own scratch space; at most
 * 4 threads + 2 layers are in flight. */
#ifndef GR_STREAM_H
#define GR_STREAM_H
#include "job.h"

/* Stream layers ga..gb; *done counts layers handed over, total is the run's
 * layer count (progress). */
int gr_stream_layers(gr_job *j, int ga, int gb, const gr_job_run_opts *r, long *done, long total, gr_err *e);

#endif
