// robot_latency: from the bumper pressed to the motors' `stop` written, in real time, through the
// whole robot side as the agent program runs it (the device layer on a copy of a reference tree,
// RobotIo, the runtime, the monotonic clock, sleeping until the runtime's next deadline).
//
//   build/bin/robot_latency [--presses N] [--tree stretch|jessie] [--dir DIR]
//
// A second thread presses the bumper (writes 1 to the touch sensor's value0) at random moments
// while `drive speed=400` runs and records when; the loop notes when it has written `stop` to both
// motors. Printed: the latency (median, 95th percentile, max), the cost of a driving tick (time
// and system calls), and the cost of an idle tick. docs/benchmarks.md keeps the figures.
#include <fcntl.h>
#include <pthread.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "ev3io/devices.hpp"
#include "ev3io/robot_io.hpp"

namespace {

namespace fs = std::filesystem;
using ev3proto::Millis;
using namespace ev3proto::robot;

std::uint64_t now_us() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::uint64_t>(ts.tv_sec) * 1000000u + static_cast<std::uint64_t>(ts.tv_nsec) / 1000u;
}

void sleep_until_us(std::uint64_t t) {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(t / 1000000u);
  ts.tv_nsec = static_cast<long>((t % 1000000u) * 1000u);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) != 0) {
  }
}

/// Sets the bumper file: one pwrite of two bytes over two bytes (no truncate: the loop never reads
/// a torn value, as from sysfs or ev3-sim).
void press(int fd, bool down) {
  if (pwrite(fd, down ? "1\n" : "0\n", 2, 0) != 2) std::perror("robot_latency: pwrite");
}

std::uint64_t percentile(std::vector<std::uint64_t> v, double p) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[std::min(v.size() - 1, static_cast<std::size_t>(p * static_cast<double>(v.size())))];
}

double ms_of(std::uint64_t us) { return static_cast<double>(us) / 1000.0; }

}  // namespace

int main(int argc, char** argv) {
  int presses = 100;
  std::string tree = "stretch", base = fs::exists("/dev/shm") ? "/dev/shm" : "/tmp";
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--presses") presses = std::atoi(argv[i + 1]);
    else if (a == "--tree") tree = argv[i + 1];
    else if (a == "--dir") base = argv[i + 1];
    else {
      std::fprintf(stderr, "usage: robot_latency [--presses N] [--tree stretch|jessie] [--dir DIR]\n");
      return 2;
    }
  }
  const std::string root = base + "/robot-latency-" + std::to_string(getpid());
  fs::copy(std::string(EV3_TREES) + "/" + tree, root, fs::copy_options::recursive | fs::copy_options::copy_symlinks);

  ev3io::Ev3Devices devices(root);
  ev3io::RobotIo rio(devices);
  const std::uint64_t t0 = now_us();
  auto ms = [t0] { return static_cast<Millis>((now_us() - t0) / 1000u); };
  Runtime rt(RuntimeConfig{}, ms());
  rio.scan(rt, ms());
  rio.flush(rt, ms());
  const std::string touch = devices.dir(Dev::in1) + "/value0";
  const int touch_fd = open(touch.c_str(), O_WRONLY | O_TRUNC | O_CLOEXEC);
  if (touch_fd < 0) {
    std::perror(touch.c_str());
    return 1;
  }
  press(touch_fd, false);

  // µs since t0 (32 bits: armv5 has no 64-bit atomics; 71 minutes of run).
  std::atomic<std::uint32_t> pressed_at{0};
  auto since_t0 = [t0] { return static_cast<std::uint32_t>(now_us() - t0); };
  std::atomic<bool> stopped{false}, done{false}, running{false};
  std::thread presser([&] {
    std::mt19937 rng(15);
    for (int i = 0; i < presses; ++i) {
      while (!running) std::this_thread::sleep_for(std::chrono::milliseconds(1));
      std::this_thread::sleep_for(std::chrono::milliseconds(100 + rng() % 300));
      stopped = false;
      pressed_at = since_t0();
      press(touch_fd, true);
      while (!stopped) std::this_thread::sleep_for(std::chrono::milliseconds(1));
      std::this_thread::sleep_for(std::chrono::milliseconds(60));
      press(touch_fd, false);
    }
    done = true;
  });

  std::vector<std::uint64_t> latency, drive_tick, idle_tick, late;
  std::vector<std::size_t> drive_calls;
  const std::string_view args[] = {"speed=400"};
  bool driving = false;
  Millis restart_at = 0;
  while (!done) {
    const Millis now = ms();
    if (now >= rio.next_scan()) rio.scan(rt, now);
    if (!driving && now >= restart_at) {
      rt.control(ev3proto::ControlKind::start, "drive", args, 1, now);
      rio.flush(rt, now);
      driving = true;
      running = true;
    }
    if (now >= rt.next_deadline()) {
      late.push_back((now - rt.next_deadline()) * 1000u);  // how late the loop woke (the host's scheduler)
      const bool moving = rt.busy();
      const std::size_t calls = devices.calls();
      const std::uint64_t a = now_us();
      rio.tick(rt, now);
      rio.flush(rt, now);
      const std::uint64_t b = now_us();
      (moving ? drive_tick : idle_tick).push_back(b - a);
      if (moving) drive_calls.push_back(devices.calls() - calls);
    }
    rio.flush(rt, now);
    for (ActionResult r; rt.poll_result(r);) {
      if (r.outcome == Outcome::interrupted && pressed_at != 0) {
        latency.push_back(since_t0() - pressed_at);  // both stops are written: flush ran above
        running = false;
        stopped = true;
        driving = false;
        restart_at = now + 200;  // the bumper is released after 60 ms; start again after
      }
    }
    for (Event e; rt.poll_event(e);) {
    }
    const Millis next = std::min({rt.next_deadline(), rio.next_scan(), driving ? Millis{~0ull} : restart_at});
    sleep_until_us(t0 + std::min<Millis>(next, ms() + 5) * 1000u);
  }
  presser.join();
  close(touch_fd);
  fs::remove_all(root);

  auto avg = [](const std::vector<std::uint64_t>& v) {
    std::uint64_t s = 0;
    for (auto x : v) s += x;
    return v.empty() ? 0 : s / v.size();
  };
  std::size_t calls_max = 0, calls_sum = 0;
  for (auto c : drive_calls) {
    calls_max = std::max(calls_max, c);
    calls_sum += c;
  }
  std::printf("tree %s under %s, %zu presses: bumper -> stop written: median %.1f ms, p95 %.1f ms, max %.1f ms\n",
              tree.c_str(), base.c_str(), latency.size(), ms_of(percentile(latency, 0.5)),
              ms_of(percentile(latency, 0.95)), ms_of(percentile(latency, 1.0)));
  std::printf("driving tick (%zu): mean %llu us, p95 %llu us, max %llu us; %.1f system calls per tick (max %zu)\n",
              drive_tick.size(), static_cast<unsigned long long>(avg(drive_tick)),
              static_cast<unsigned long long>(percentile(drive_tick, 0.95)),
              static_cast<unsigned long long>(percentile(drive_tick, 1.0)),
              drive_calls.empty() ? 0.0 : static_cast<double>(calls_sum) / static_cast<double>(drive_calls.size()), calls_max);
  std::printf("idle tick (%zu): mean %llu us; ticks late by p95 %.1f ms, max %.1f ms\n", idle_tick.size(),
              static_cast<unsigned long long>(avg(idle_tick)), ms_of(percentile(late, 0.95)), ms_of(percentile(late, 1.0)));
  return 0;
}
