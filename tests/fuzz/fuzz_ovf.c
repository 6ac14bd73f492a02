/* fuzz_ovf.c: libFuzzer harness for the OVF reader (engine/ovf_read.c).
 * Any bytes go through gr_ovf_read_mem (job LUT, job shell, every work
 * plane through its LUT and blocks); the reader must return an error or
 * GR_OK, never crash, leak or read outside the buffer. Seeds: tests/fuzz/ovf/.
 * Build (with the engine's core objects and libprotobuf-c, under
 * -fsanitize=fuzzer,address,undefined): see the Makefile's fuzz target. */
#include <stdint.h>
#include <stdlib.h>
#include "ovf.h"

static int count_blocks(void *ud, const gr_layer *l, const int *style, const gr_cli_header *h, gr_err *e) {
  (void)e;
  size_t *n = ud;
  for (size_t b = 0; b < l->nb; b++)
    if (style[b] >= 0 && style[b] < h->nstyles) (*n)++; /* every style index must be valid */
    else abort();
  return GR_OK;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  gr_cli_header *h = malloc(sizeof *h);
  if (!h) return 0;
  gr_err e;
  gr_err_clear(&e);
  size_t blocks = 0;
  gr_ovf_read_mem("fuzz.ovf", data, size, h, count_blocks, &blocks, &e);
  free(h);
  return 0;
}
