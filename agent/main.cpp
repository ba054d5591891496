// ev3-agent: one robot of the fleet. The I/O around the agent core (libev3proto agent.hpp): a UDP
// socket, one event loop (ppoll) that sleeps until the next datagram or the next deadline (core,
// behaviour runner, copy sends, log flush), the LEDs, the `wait` behaviour runner, logging and the
// NDJSON trace. docs/programs.md describes the command line.
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <optional>
#include <cstring>
#include <map>
#include <string>
#include <vector>

#include <ev3proto/agent.hpp>
#include <ev3proto/trace.hpp>
#include <ev3proto/wire.hpp>

#include "ev3io/log.hpp"
#include "ev3io/loop.hpp"
#include "ev3io/udp.hpp"
#include "leds.hpp"
#include "agent_options.hpp"
#include "driver.hpp"
#include "wait_runner.hpp"

namespace {

using ev3io::kDebug;
using ev3io::kError;
using ev3io::kInfo;
using ev3io::kVerbose;
using ev3proto::Millis;

// Device bits of model A (the thesis' test robot): two large motors, ultrasonic, touch, colour.
constexpr std::uint32_t kMotorLeft = 1u << 0, kMotorRight = 1u << 1, kUltrasonic = 1u << 2,
                        kTouch = 1u << 3, kColour = 1u << 4;
// Behaviours of model A: `wait` needs no device.
constexpr ev3proto::BehaviourSpec kModelABehaviours[] = {{"wait", 0}};

std::uint64_t random_u64() {
  std::uint64_t v = 0;
  const int fd = open("/dev/urandom", O_RDONLY | O_CLOEXEC);
  if (fd >= 0) {
    if (read(fd, &v, sizeof v) != static_cast<ssize_t>(sizeof v)) v = 0;
    close(fd);
  }
  if (v == 0) v = (ev3io::monotonic_ms() << 16) ^ static_cast<std::uint64_t>(static_cast<unsigned>(getpid()));
  return v;
}

/// Printable form of a datagram for the log (at most 100 bytes).
std::string printable(std::string_view d) {
  std::string s;
  for (std::size_t i = 0; i < d.size() && i < 100; ++i) {
    const auto c = static_cast<unsigned char>(d[i]);
    if (c >= 0x20 && c < 0x7F) {
      s += static_cast<char>(c);
    } else {
      char b[5];
      std::snprintf(b, sizeof b, "\\x%02X", c);
      s += b;
    }
  }
  if (d.size() > 100) s += "...";
  return s;
}

std::string reason_key(ev3proto::Reason r) {
  std::string k = "decode:" + std::string(ev3proto::to_string(r));
  for (char& c : k)
    if (c == ' ') c = '_';
  return k;
}

std::string counters_line(const std::map<std::string, std::uint64_t>& m) {
  std::string s;
  for (const auto& kv : m) {
    if (!s.empty()) s += ' ';
    s += kv.first + "=" + std::to_string(kv.second);
  }
  return s.empty() ? "none" : s;
}

using AgentCore = ev3proto::Agent<ev3proto::NdjsonTrace>;

class Program {
 public:
  explicit Program(const ev3agent::AgentOptions& o) : opt_(o), net_(o.common.faults) {}

  int run() {
    log_.set_name("agent");
    log_.set_level(opt_.common.log_level);
    if (!opt_.common.log_file.empty() && !log_.open(opt_.common.log_file)) {
      std::fprintf(stderr, "ev3-agent: bad value for --log-file: cannot open '%s': %s\n",
                   opt_.common.log_file.c_str(), std::strerror(errno));
      return 2;
    }
    if (!opt_.common.trace_file.empty()) {
      trace_file_ = std::fopen(opt_.common.trace_file.c_str(), "w");
      if (trace_file_ == nullptr) {
        std::fprintf(stderr, "ev3-agent: bad value for --trace: cannot open '%s': %s\n",
                     opt_.common.trace_file.c_str(), std::strerror(errno));
        return 2;
      }
      trace_.set_output([this](const std::string& line) {
        std::fwrite(line.data(), 1, line.size(), trace_file_);
        std::fputc('\n', trace_file_);
      });
    }
    std::string err;
    if (!net_.open(opt_.common.bind_addr, opt_.common.port, err)) {
      log_.log(kError, "%s", err.c_str());
      log_.flush();
      std::fprintf(stderr, "ev3-agent: %s\n", err.c_str());
      return 1;
    }
    ev3proto::AgentConfig cfg;
    cfg.caps = {opt_.model, kModelABehaviours, 1, kMotorLeft | kMotorRight | kUltrasonic | kTouch | kColour};
    cfg.timers = opt_.timers;
    const std::uint64_t r = random_u64();
    cfg.temp_id = static_cast<std::uint16_t>(ev3proto::kFirstTempId + r % 15536u);
    cfg.first_msgid = static_cast<std::uint32_t>(1 + (r >> 20) % 1000000000u);
    if (opt_.model != "A")
      log_.log(kInfo, "model %s: using model A's capability table (wait)", opt_.model.c_str());
    const Millis now = ev3io::monotonic_ms();
    agent_.emplace(cfg, now, trace_file_ != nullptr ? &trace_ : nullptr);
    leds_.emplace(opt_.sysfs_root, log_);
    leds_->set(agent_->led());
    std::string bc;
    for (const auto& e : opt_.common.broadcast) bc += " " + e.str();
    log_.log(kInfo, "listening on %s (model %s, temporary id %u, broadcast to%s)", net_.local().str().c_str(),
             opt_.model.c_str(), cfg.temp_id, bc.c_str());
    log_.log(kInfo, "state IDLE");
    log_.flush();
    loop();
    shutdown();
    return 0;
  }

 private:
  void loop() {
    std::string dgram;
    ev3io::Endpoint from;
    Millis next_summary = ev3io::monotonic_ms() + 5000;
    while (signals_.stop_signal() == 0) {
      Millis now = ev3io::monotonic_ms();
      while (net_.receive(dgram, from)) {
        now = ev3io::monotonic_ms();
        on_datagram(dgram, from, now);
      }
      now = ev3io::monotonic_ms();
      run_behaviour(now);
      agent_->advance(now);
      pump(now);
      net_.flush(now);
      if (now >= next_summary) {
        if (drops_changed_) log_.log(kVerbose, "drops: %s", counters_line(drops_).c_str());
        drops_changed_ = false;
        next_summary = now + 5000;
      }
      Millis deadline = agent_->next_deadline();
      deadline = std::min(deadline, runner_.deadline());
      deadline = std::min(deadline, net_.next_send());
      deadline = std::min(deadline, log_.tick(now));
      deadline = std::min(deadline, next_summary);
      if (trace_file_ != nullptr) {
        if (now >= trace_flush_) {
          std::fflush(trace_file_);
          trace_flush_ = now + 200;
        }
        deadline = std::min(deadline, trace_flush_);
      }
      pollfd p{net_.fd(), POLLIN, 0};
      signals_.wait(&p, 1, deadline);
    }
  }

  void drop(const std::string& why, std::string_view d) {
    const std::uint64_t n = ++drops_[why];
    drops_changed_ = true;
    if (log_.enabled(kVerbose))
      log_.log(kVerbose, "drop (%s, %llu so far): %s", why.c_str(), static_cast<unsigned long long>(n),
               printable(d).c_str());
  }

  void on_datagram(const std::string& d, const ev3io::Endpoint& from, Millis now) {
    const ev3proto::DecodeResult dr = ev3proto::decode(d, rx_);
    if (!dr.ok()) {
      drop(reason_key(dr.reason), d);
      agent_->handle_datagram(d, 0, now);  // the core counts it too (rejected())
      return;
    }
    const std::uint16_t my_id = agent_->id();
    const ev3proto::Peer peer = net_.peer_of(from);
    log_.log(kDebug, "recv %s from %s", printable(d).c_str(), from.str().c_str());
    const ev3proto::Action a = agent_->handle_datagram(d, peer, now);
    if (a == ev3proto::Action::Ignore) {
      if (rx_.receiver != my_id && rx_.receiver != ev3proto::kBroadcastId)
        drop("misaddressed", d);
      else if (rx_.sender != ev3proto::kMasterId)
        drop("foreign_sender", d);
      else if (agent_->window().contains(rx_.sender, rx_.msgid))
        drop("stale", d);
      else
        drop("ignored_in_state", d);
    } else if (a == ev3proto::Action::RecvDuplicate) {
      ++drops_["duplicate_answered_again"];
      log_.log(kDebug, "duplicate %s answered again", printable(d).c_str());
    }
    pump(now);
  }

  void run_behaviour(Millis now) {
    switch (runner_.poll(now)) {
      case ev3agent::WaitRunner::Outcome::ok:
        log_.log(kInfo, "behaviour wait: %llu ms are up, ACTION_OK",
                 static_cast<unsigned long long>(runner_.total()));
        agent_->action_ok(now);
        pump(now);
        break;
      case ev3agent::WaitRunner::Outcome::failed:
        log_.log(kError, "behaviour cannot run: %s; ACTION_ERR", runner_.error().c_str());
        agent_->action_failed(now);
        pump(now);
        break;
      case ev3agent::WaitRunner::Outcome::none: break;
    }
  }

  /// Drains the core's outputs after every call into it.
  void pump(Millis now) {
    ev3proto::Transmit t;
    while (agent_->poll_transmit(t)) {
      log_.log(kDebug, "send %s to %s", printable(t.bytes).c_str(), std::string(to_string(t.dest)).c_str());
      const ev3io::Endpoint* ep = t.dest == ev3proto::Dest::master ? net_.endpoint_of(t.peer) : nullptr;
      if (ep != nullptr) {
        master_peer_ = t.peer;
        net_.send(*ep, t.bytes, now);
      } else {
        for (const auto& b : opt_.common.broadcast) net_.send(b, t.bytes, now);
      }
    }
    ev3proto::AgentEvent e;
    while (agent_->poll_event(e)) {
      switch (e.kind) {
        case ev3proto::AgentEvent::Kind::state:
          log_.log(kInfo, "state %s (id %u)", std::string(to_string(e.state)).c_str(), agent_->id());
          break;
        case ev3proto::AgentEvent::Kind::led: leds_->set(e.led); break;
        case ev3proto::AgentEvent::Kind::control: {
          const ev3proto::BehaviourView b = agent_->behaviour();
          std::vector<std::string_view> args;
          for (std::size_t i = 0; i < b.arg_count; ++i) args.push_back(b.arg(i));
          const Millis left_before = runner_.left(now);
          runner_.control(e.control, b.name, args, now);
          log_.log(kInfo, "behaviour %s: %s (%llu ms left)", std::string(b.name).c_str(),
                   std::string(to_string(e.control)).c_str(),
                   static_cast<unsigned long long>(e.control == ev3proto::ControlKind::stop ? left_before
                                                                                       : runner_.left(now)));
          break;
        }
      }
    }
  }

  void shutdown() {
    const Millis now = ev3io::monotonic_ms();
    log_.log(kInfo, "stopping (signal %d)", signals_.stop_signal());
    if (runner_.phase() == ev3agent::WaitRunner::Phase::running ||
        runner_.phase() == ev3agent::WaitRunner::Phase::paused) {
      runner_.control(ev3proto::ControlKind::stop, "", {}, now);
      log_.log(kInfo, "behaviour stopped, motors stopped");
    }
    if (ev3proto::is_synced(agent_->state())) {
      // The protocol has no "leaving" message: an EVENT named LEAVING tells the master.
      char buf[64];
      const std::string_view p[1] = {"LEAVING"};
      const auto r = ev3proto::encode_parts(agent_->id(), ev3proto::kMasterId, agent_->next_msgid(),
                                            static_cast<std::uint8_t>(ev3proto::MsgType::EVENT), p, 1, buf,
                                            sizeof buf);
      const ev3io::Endpoint* ep = net_.endpoint_of(master_peer_);
      if (r.ok() && ep != nullptr) {
        net_.send(*ep, std::string_view(buf, r.size), now);
        log_.log(kInfo, "told the master: EVENT LEAVING");
      }
    }
    net_.flush_all();
    log_.log(kInfo, "drops: %s", counters_line(drops_).c_str());
    leds_->set(ev3proto::Led::DARK);
    log_.flush();
    if (trace_file_ != nullptr) {
      std::fclose(trace_file_);
      trace_file_ = nullptr;
    }
  }

  ev3agent::AgentOptions opt_;
  ev3io::Logger log_;
  ev3io::Signals signals_;
  ev3io::UdpTransport net_;
  ev3proto::NdjsonTrace trace_{"agent"};
  std::FILE* trace_file_ = nullptr;
  Millis trace_flush_ = 0;
  std::optional<AgentCore> agent_;
  std::optional<ev3agent::Leds> leds_;
  ev3agent::WaitRunner runner_;
  ev3proto::Message rx_;
  std::map<std::string, std::uint64_t> drops_;
  bool drops_changed_ = false;
  ev3proto::Peer master_peer_ = 0;  // the master's handle, as the core last sent to it
};

}  // namespace

int main(int argc, char** argv) {
  // Driver mode (docs/driver.md): the core on a virtual clock, NDJSON on stdin/stdout; no sockets.
  for (int i = 1; i < argc; ++i)
    if (std::strcmp(argv[i], "--driver") == 0) return ev3agent::run_driver(argc, argv);
  ev3agent::AgentOptions o;
  std::string msg;
  switch (ev3agent::parse_agent_options(argc, argv, o, msg)) {
    case ev3agent::ParseOutcome::help: std::printf("%s", msg.c_str()); return 0;
    case ev3agent::ParseOutcome::error:
      std::fprintf(stderr, "ev3-agent: %s (try --help)\n", msg.c_str());
      return 2;
    case ev3agent::ParseOutcome::run: break;
  }
  static Program p(o);  // static: the core and the receive message are large
  return p.run();
}
