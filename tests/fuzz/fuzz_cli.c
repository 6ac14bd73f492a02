/* libFuzzer harness: the CLI reader (engine/cli.c), ASCII and binary. The
 * reader maps a regular file, so each input goes to an in-memory file
 * (memfd) read through /proc/self/fd. Every layer handed over is measured. */
#define _GNU_SOURCE
#include <stdint.h>
#include <stdio.h>
#include <sys/mman.h>
#include <unistd.h>
#include "cli.h"

static int measure(void *ud, const gr_layer *l, gr_err *e) {
  (void)e;
  double *len = ud;
  for (size_t b = 0; b < l->nb; b++) *len += gr_block_length(l, &l->b[b]);
  return GR_OK;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  if (size > (1 << 20)) return 0;
  int fd = memfd_create("fuzz.cli", 0);
  if (fd < 0) return 0;
  if (write(fd, data, size) == (ssize_t)size) {
    char path[64];
    snprintf(path, sizeof path, "/proc/self/fd/%d", fd);
    gr_cli_header h;
    gr_err e;
    double len = 0;
    gr_cli_read(path, &h, measure, &len, &e);
  }
  close(fd);
  return 0;
}
