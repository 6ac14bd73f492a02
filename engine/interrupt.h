/* interrupt.h: Ctrl-C (SIGINT) as a request to stop. The host's signal
 * handler calls gr_interrupt_request (async-signal-safe); code that can stop
 * cleanly polls gr_interrupted (the layer writer between layers; the Lua hook
 * between instructions) and fails with a message that says where it
 * stopped, so every temporary is removed on the way out. The first one to
 * report it calls gr_interrupt_reported, so it is reported once.
 * The flag is the one piece of process-wide mutable state: a signal has no
 * other place to leave its news. */
#ifndef GR_INTERRUPT_H
#define GR_INTERRUPT_H

void gr_interrupt_request(void);  /* from a signal handler */
int gr_interrupted(void);         /* 0 none, 1 requested, 2 requested and reported */
void gr_interrupt_reported(void); /* the stop has been reported (state 2) */
void gr_interrupt_clear(void);    /* back to 0 */

#endif
