/* view_serve.h: `gradus view FILE --serve`: the viewer page and one layer
 * per request over HTTP on 127.0.0.1, through libmicrohttpd. */
#ifndef GR_VIEW_SERVE_H
#define GR_VIEW_SERVE_H
#include "view.h"

typedef struct gr_view_serve_opts {
  int port;              /* TCP port on 127.0.0.1; 0: one the system picks */
  const char *page;      /* the HTML answered at / (not copied: keep it alive) */
  size_t page_len;
  double quantum;        /* coordinate step of the layer encoding, mm */
  /* called once the server listens, with the port it got; non-zero (with
   * e filled) stops the server and is returned */
  int (*ready)(void *ud, int port, gr_err *e);
  void *ud;
} gr_view_serve_opts;

/* Serve until SIGINT or SIGTERM arrives (those are blocked in the calling
 * thread while serving, then restored). Requests:
 *   GET /            the page
 *   GET /layer/K     layer K (1-based) in the viewer encoding (view.h),
 *                    application/octet-stream
 * A layer out of range or a malformed K is a 404 whose text names the range;
 * a layer the reader refuses is a 500 with the reader's message; any other
 * path 404, any other method 405. Each layer is read from the file on
 * request (the file is mapped only while that layer is read).
 * Errors: the port cannot be bound (GR_EIO), ready's code. */
int gr_view_serve(const gr_view_index *ix, const gr_view_serve_opts *o, gr_err *e);

#endif
