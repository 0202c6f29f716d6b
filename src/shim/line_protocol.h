/* The side channel between the preload shim (src/shim/serial_lines.c) and
 * the bridge (src/bridge/line_channel.cpp): what a program under `--as` does
 * to the serial lines of its redirected descriptor (DESIGN §20), which a pty
 * cannot carry. A SOCK_SEQPACKET Unix socket at the path in
 * WIRETAPE_LINE_CHANNEL; both ends are on this machine, so the messages are
 * fixed-size structs in native byte order. Each request gets one reply.
 *
 * A request carries the client's count of bytes written to the redirected
 * descriptors so far (since its hello), because a write to the pty can
 * return before its bytes are readable at the master: the bridge applies a
 * line change once it has relayed that many of the client's bytes, so that
 * the change falls exactly where the client made it among its bytes.
 *
 * Included by C and C++. */
#ifndef WIRETAPE_SHIM_LINE_PROTOCOL_H
#define WIRETAPE_SHIM_LINE_PROTOCOL_H

#include <stdint.h>

#define WT_LINE_ENV "WIRETAPE_LINE_CHANNEL"
#define WT_LINE_MAGIC 0x57544c31u /* "WTL1" */

enum wt_line_op {
  /* First message of a connection: `written` counts from here. */
  WT_LINE_HELLO = 1,
  /* Outputs: raise the TIOCM_DTR/TIOCM_RTS bits in `set`, lower those in
   * `clear`. */
  WT_LINE_SET_OUTPUTS = 2,
  /* A timed break of `value` milliseconds. */
  WT_LINE_BREAK = 3,
  WT_LINE_BREAK_ON = 4,
  WT_LINE_BREAK_OFF = 5,
  /* The client changed the terminal's settings (the bridge reads them from
   * the pty's master, custom baud included). */
  WT_LINE_SETTINGS = 6,
  /* Reply once every byte written so far has been relayed (tcdrain). */
  WT_LINE_DRAIN = 7,
  /* Replies with the lines (inputs and outputs) and the input counters. */
  WT_LINE_GET = 8,
  /* Replies when an input among the TIOCM bits in `set` changes. */
  WT_LINE_WAIT = 9
};

struct wt_line_request {
  uint32_t magic;
  uint32_t op;
  uint64_t written;
  uint32_t set;
  uint32_t clear;
  uint32_t value;
  uint32_t reserved;
};

struct wt_line_reply {
  int32_t error; /* 0, or an errno value for the client's call */
  uint32_t lines; /* TIOCM_* bits: the device's inputs and the outputs */
  /* How often each input changed (TIOCGICOUNT). */
  uint32_t cts_changes;
  uint32_t dsr_changes;
  uint32_t ri_changes;
  uint32_t cd_changes;
};

#endif
