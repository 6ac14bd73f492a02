/* libFuzzer harness: the knowledge-base template decoder (engine/kb.c,
 * gr_template_decode), which must never trust its input. A blob that
 * decodes must encode again to the same bytes. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include "kb.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  gr_template *t = NULL;
  gr_err e;
  if (gr_template_decode(data, size, &t, &e) == GR_OK) {
    unsigned char *buf = NULL;
    size_t n = 0;
    if (gr_template_encode(t, &buf, &n, &e) != GR_OK) abort();
    gr_template *u = NULL;
    if (gr_template_decode(buf, n, &u, &e) != GR_OK) abort();
    gr_template_free(u);
    free(buf);
  }
  gr_template_free(t);
  return 0;
}
