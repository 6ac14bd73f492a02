/* view_serve.c: the viewer's HTTP server on libmicrohttpd, see view_serve.h. */
#include "view_serve.h"
#include <arpa/inet.h>
#include <errno.h>
#include <microhttpd.h>
#include <netinet/in.h>
#include <signal.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

typedef struct server {
  const gr_view_index *ix;
  const gr_view_serve_opts *o;
} server;

static enum MHD_Result answer(struct MHD_Connection *c, unsigned status, const char *type, void *buf, size_t n,
                              enum MHD_ResponseMemoryMode mode) {
  struct MHD_Response *r = MHD_create_response_from_buffer(n, buf, mode);
  if (!r) {
    if (mode == MHD_RESPMEM_MUST_FREE) free(buf);
    return MHD_NO;
  }
  MHD_add_response_header(r, MHD_HTTP_HEADER_CONTENT_TYPE, type);
  MHD_add_response_header(r, MHD_HTTP_HEADER_CACHE_CONTROL, "no-store");
  enum MHD_Result ok = MHD_queue_response(c, status, r);
  MHD_destroy_response(r);
  return ok;
}

static enum MHD_Result text(struct MHD_Connection *c, unsigned status, const char *msg) {
  size_t n = strlen(msg);
  char *m = malloc(n + 1);
  if (!m) return MHD_NO;
  memcpy(m, msg, n);
  m[n] = '\n';
  return answer(c, status, "text/plain; charset=utf-8", m, n + 1, MHD_RESPMEM_MUST_FREE);
}

typedef struct enc { gr_view_buf b; double quantum; } enc;

static int encode_layer(void *ud, const gr_layer *l, gr_err *e) {
  enc *x = ud;
  return gr_view_encode(l, x->quantum, &x->b, e);
}

/* GET /layer/K: K must be all digits and 1..n. */
static enum MHD_Result layer(const server *s, struct MHD_Connection *c, const char *k) {
  char msg[600];
  size_t n = s->ix->n, want = 0;
  int digits = *k && strspn(k, "0123456789") == strlen(k) && strlen(k) < 19;
  if (digits) want = strtoull(k, NULL, 10);
  if (!digits || want < 1 || want > n) {
    snprintf(msg, sizeof msg, "layer %.40s is out of range: %s has %zu layers (1..%zu)", k, s->ix->path, n, n);
    return text(c, MHD_HTTP_NOT_FOUND, msg);
  }
  enc x = {{NULL, 0, 0}, s->o->quantum};
  gr_err e;
  gr_err_clear(&e);
  if (gr_view_layer(s->ix, want - 1, encode_layer, &x, &e)) {
    free(x.b.p);
    return text(c, MHD_HTTP_INTERNAL_SERVER_ERROR, e.msg);
  }
  return answer(c, MHD_HTTP_OK, "application/octet-stream", x.b.p, x.b.n, MHD_RESPMEM_MUST_FREE);
}

static enum MHD_Result on_request(void *cls, struct MHD_Connection *c, const char *url, const char *method,
                                  const char *version, const char *upload, size_t *upload_size, void **state) {
  (void)version, (void)upload, (void)upload_size, (void)state;
  const server *s = cls;
  if (strcmp(method, "GET") && strcmp(method, "HEAD")) return text(c, MHD_HTTP_METHOD_NOT_ALLOWED, "only GET");
  if (!strcmp(url, "/") || !strcmp(url, "/index.html"))
    return answer(c, MHD_HTTP_OK, "text/html; charset=utf-8", (void *)s->o->page, s->o->page_len,
                  MHD_RESPMEM_PERSISTENT);
  if (!strncmp(url, "/layer/", 7)) return layer(s, c, url + 7);
  return text(c, MHD_HTTP_NOT_FOUND, "not found (the page is at /, layers at /layer/K)");
}

int gr_view_serve(const gr_view_index *ix, const gr_view_serve_opts *o, gr_err *e) {
  if (o->port < 0 || o->port > 65535) return gr_fail(e, GR_EARG, "port must be 0..65535, got %d", o->port);
  if (!(o->quantum > 0)) return gr_fail(e, GR_EARG, "quantum must be > 0 mm, got %g", o->quantum);
  server s = {ix, o};
  struct sockaddr_in a;
  memset(&a, 0, sizeof a);
  a.sin_family = AF_INET;
  a.sin_port = htons((uint16_t)o->port);
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  /* block the stop signals before the server's thread starts (it inherits
   * the mask), so that they reach sigwait below and nothing else */
  sigset_t stop, old;
  sigemptyset(&stop);
  sigaddset(&stop, SIGINT);
  sigaddset(&stop, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &stop, &old);
  /* a shell starts background jobs with SIGINT ignored, and an ignored
   * signal never reaches sigwait: default actions while serving (blocked,
   * so they cannot kill), the old ones restored afterwards */
  struct sigaction dfl, old_int, old_term;
  memset(&dfl, 0, sizeof dfl);
  dfl.sa_handler = SIG_DFL;
  sigaction(SIGINT, &dfl, &old_int);
  sigaction(SIGTERM, &dfl, &old_term);
  struct MHD_Daemon *d = MHD_start_daemon(MHD_USE_INTERNAL_POLLING_THREAD, 0, NULL, NULL, on_request, &s,
                                          MHD_OPTION_SOCK_ADDR, (struct sockaddr *)&a, MHD_OPTION_END);
  int rc = GR_OK;
  if (!d) {
    rc = gr_fail(e, GR_EIO, "cannot listen on 127.0.0.1:%d (%s)", o->port,
                 errno ? strerror(errno) : "the port may be in use");
  } else {
    const union MHD_DaemonInfo *di = MHD_get_daemon_info(d, MHD_DAEMON_INFO_BIND_PORT);
    int port = di ? di->port : o->port;
    if (o->ready) rc = o->ready(o->ud, port, e);
    if (!rc) {
      int sig;
      while (sigwait(&stop, &sig) != 0) {}
    }
    MHD_stop_daemon(d);
  }
  sigaction(SIGINT, &old_int, NULL);
  sigaction(SIGTERM, &old_term, NULL);
  pthread_sigmask(SIG_SETMASK, &old, NULL);
  return rc;
}
