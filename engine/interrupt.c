/* interrupt.c: see interrupt.h. */
#include "interrupt.h"
#include <signal.h>

static volatile sig_atomic_t state;

void gr_interrupt_request(void) {
  if (state == 0) state = 1;
}
int gr_interrupted(void) { return state; }
void gr_interrupt_reported(void) { state = 2; }
void gr_interrupt_clear(void) { state = 0; }
