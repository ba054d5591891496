#include "ev3io/loop.hpp"

#include <signal.h>
#include <time.h>

#include <cerrno>

namespace ev3io {

namespace {
volatile sig_atomic_t g_stop = 0;
extern "C" void on_stop_signal(int sig) { g_stop = sig; }
sigset_t g_unblocked;
}  // namespace

Millis monotonic_ms() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<Millis>(ts.tv_sec) * 1000u + static_cast<Millis>(ts.tv_nsec / 1000000);
}

std::uint64_t wall_ms() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::uint64_t>(ts.tv_sec) * 1000u + static_cast<std::uint64_t>(ts.tv_nsec / 1000000);
}

Signals::Signals() noexcept {
  struct sigaction sa {};
  sa.sa_handler = on_stop_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  struct sigaction ign {};
  ign.sa_handler = SIG_IGN;
  sigemptyset(&ign.sa_mask);
  sigaction(SIGPIPE, &ign, nullptr);
  sigset_t block;
  sigemptyset(&block);
  sigaddset(&block, SIGINT);
  sigaddset(&block, SIGTERM);
  sigprocmask(SIG_BLOCK, &block, &g_unblocked);
  sigdelset(&g_unblocked, SIGINT);
  sigdelset(&g_unblocked, SIGTERM);
}

int Signals::stop_signal() const noexcept { return static_cast<int>(g_stop); }

int Signals::wait(pollfd* fds, std::size_t n, Millis deadline) const noexcept {
  if (g_stop) return 0;
  timespec ts{};
  timespec* tp = nullptr;
  if (deadline != kNever) {
    const Millis now = monotonic_ms();
    const Millis d = deadline > now ? deadline - now : 0;
    ts.tv_sec = static_cast<time_t>(d / 1000u);
    ts.tv_nsec = static_cast<long>((d % 1000u) * 1000000u);
    tp = &ts;
  }
  const int r = ppoll(fds, static_cast<nfds_t>(n), tp, &g_unblocked);
  return r < 0 ? 0 : r;
}

}  // namespace ev3io
