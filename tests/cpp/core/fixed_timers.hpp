// The timers the core transcripts and tests are written with: round seconds (heartbeat 1 s,
// master timeout 3 s, back-off 3 s ...; no back-off jitter, no vouching rules), fixed here and not the library's defaults (timers.hpp), so
// that the transcripts read the same whatever the defaults are. Timers.DefaultsAndSpecMapping
// checks the defaults themselves.
#pragma once

#include "ev3proto/timers.hpp"

namespace ev3test {

inline ev3proto::Timers fixed_timers() {
  using ev3proto::Timer;
  ev3proto::Timers t;
  t.set(Timer::sync, 10000).set(Timer::heartbeat, 1000).set(Timer::loss, 3000).set(Timer::paused, 6000);
  t.set(Timer::resend, 500).set(Timer::drop, 10000).set(Timer::relay_retry, 1000).set(Timer::backoff, 3000);
  t.set(Timer::backoff_step, 100).set(Timer::candidate, 2000).set(Timer::leader_heartbeat, 1000);
  t.set(Timer::backoff_jitter, 0).set(Timer::vouch, 0);  // off unless a transcript turns them on
  return t;
}

}  // namespace ev3test
