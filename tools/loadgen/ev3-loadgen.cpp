// ev3-loadgen: N simulated agents against one ev3-master over UDP, to measure how many agents one
// master keeps and how fast it answers (docs/benchmarks.md, "Master at scale").
//
// Each simulated agent is a real agent core (libev3proto agent.hpp, no behaviours, no devices) with
// its own UDP socket on its own port: the master tells agents apart by their address, so one socket
// per agent is what a fleet looks like to it. Everything an agent sends goes to the master address
// (AGENT / PANIC broadcasts included), 3 copies a few ms apart as the real transport sends them. One
// thread, one epoll over all sockets; agent deadlines in a min-heap (lazy: stale items are skipped).
//
// Agents start spread over --ramp-s, sync, and then PING every --heartbeat-ms. Once all are synced
// (or after --settle-s) the measurement window of --duration-s begins: PONG latency (PING's first
// copy sent -> its PONG's first copy received), PINGs left without PONG, and agents that lost the
// master (HeartbeatLost: no answer for --master-timeout-ms -> PANIC). With --master-status FILE (the
// master's --status-json), the master's own count of agents it declared lost is read at the end,
// and the file's age is sampled every 100 ms of the window (a master that starves its loop under
// load stops rewriting it: it should be at most about 0.5 s old). The CPU time of this program and,
// with --master-pid, of the master over the window are reported as a share of one core.
// With --report-ms N the agents take the behaviour `wait` (the master sends BEHAVIOUR and START, a
// script of its own) and, while WORKING, each makes a SENSOR_VALUE report every N ms: numbered,
// acknowledged by the master, a row of its --db record each; the window then begins once every
// agent is WORKING.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/epoll.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <queue>
#include <sstream>
#include <string>
#include <vector>

#include <ev3proto/agent.hpp>
#include <ev3proto/wire.hpp>

#include "ev3io/cli.hpp"

namespace {

using ev3proto::Millis;

using Micros = std::uint64_t;
constexpr Millis kNever = ~Millis{0};
Micros now_us() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<Micros>(ts.tv_sec) * 1000000u + static_cast<Micros>(ts.tv_nsec / 1000);
}

volatile std::sig_atomic_t g_stop = 0;
extern "C" void on_signal(int) { g_stop = 1; }

struct Options {
  ev3io::Endpoint master;
  std::uint32_t bind_addr = 0;
  std::size_t agents = 0;
  Millis heartbeat = 1000, loss = 3000, paused = 6000, sync = 10000;
  double ramp_s = 5, settle_s = 60, duration_s = 30;
  unsigned copies = 3;
  Millis copy_gap = 3;
  std::uint16_t first_temp_id = ev3proto::kFirstTempId;
  std::string master_status;
  long master_pid = 0;
  Millis report_ms = 0;  // a SENSOR_VALUE report this often while WORKING (0: none)
  bool json = false;
};

const std::vector<ev3io::OptionSpec> kSpecs = {
    {"master", "HOST:PORT", "the ev3-master to load (required)"},
    {"agents", "N", "simulated agents, one UDP socket each (required; 1..15536)"},
    {"bind", "ADDR", "address the agents' sockets bind (default 127.0.0.1)"},
    {"heartbeat-ms", "N", "agent heartbeat: AGENT / PING / PANIC period (default 1000)"},
    {"master-timeout-ms", "N", "agent: master silent this long -> PANIC (default 3000)"},
    {"paused-timeout-ms", "N", "agent: PAUSED this long without master -> PANIC (default 6000)"},
    {"sync-timeout-ms", "N", "agent: IDLE this long without MASTER -> PANIC (default 10000)"},
    {"ramp-s", "S", "agents start spread over this many seconds (default 5)"},
    {"settle-s", "S", "wait at most this long for every agent to sync (default 60)"},
    {"duration-s", "S", "the measurement window after that (default 30)"},
    {"copies", "N", "copies of every datagram, as the transport sends (default 3)"},
    {"copy-gap-ms", "N", "between two copies (default 3)"},
    {"first-temp-id", "N", "agent i announces temporary id N + i (default 50000)"},
    {"master-status", "FILE", "the master's --status-json: report its agents and lost ones at the end"},
    {"master-pid", "PID", "the master's process: report its CPU time over the window"},
    {"report-ms", "N", "while WORKING (the master sent BEHAVIOUR wait and START), each agent makes a SENSOR_VALUE "
                       "report this often, 1..60000 (default: none)"},
    {"json", "", "print the summary as one JSON object"},
};

const char* kSynopsis =
    "ev3-loadgen --master HOST:PORT --agents N [--heartbeat-ms N] [--duration-s S] [--ramp-s S]\n"
    "            [--settle-s S] [--master-timeout-ms N] [--copies N] [--master-status FILE]\n"
    "            [--master-pid PID] [--report-ms N] [--json]";

/// Parses the options; "" or an error naming the bad one.
std::string parse(int argc, char** argv, Options& o, bool& help) {
  ev3io::ParsedArgs a;
  std::string err = ev3io::parse_args(argc, argv, kSpecs, "", a);
  if (!err.empty()) return err;
  help = a.help;
  if (help) return {};
  if (!a.has("master") || !ev3io::parse_endpoint(a.get("master"), o.master))
    return "--master HOST:PORT is required (e.g. --master 127.0.0.1:12345)";
  std::uint64_t v = 0;
  if (!ev3io::to_uint(a.get("agents"), 1, 65536 - ev3proto::kFirstTempId, v))
    return "--agents N is required: 1..15536 (each agent needs its own temporary id)";
  o.agents = static_cast<std::size_t>(v);
  if (!ev3io::parse_address(a.get("bind", "127.0.0.1"), o.bind_addr)) return "bad value for --bind: '" + a.get("bind") + "'";
  const struct {
    const char* name;
    Millis* out;
  } ms[] = {{"heartbeat-ms", &o.heartbeat}, {"master-timeout-ms", &o.loss}, {"paused-timeout-ms", &o.paused},
            {"sync-timeout-ms", &o.sync}, {"copy-gap-ms", &o.copy_gap}};
  for (const auto& m : ms)
    if (a.has(m.name)) {
      if (!ev3io::to_uint(a.get(m.name), 1, 3600000, v)) return std::string("bad value for --") + m.name + ": '" + a.get(m.name) + "'";
      *m.out = v;
    }
  if (o.paused <= o.loss) return "--paused-timeout-ms must be above --master-timeout-ms";
  const struct {
    const char* name;
    double* out;
  } secs[] = {{"ramp-s", &o.ramp_s}, {"settle-s", &o.settle_s}, {"duration-s", &o.duration_s}};
  for (const auto& s : secs)
    if (a.has(s.name) && !ev3io::to_double(a.get(s.name), 0, 86400, *s.out))
      return std::string("bad value for --") + s.name + ": '" + a.get(s.name) + "'";
  if (a.has("copies")) {
    if (!ev3io::to_uint(a.get("copies"), 1, 10, v)) return "bad value for --copies: '" + a.get("copies") + "' (1..10)";
    o.copies = static_cast<unsigned>(v);
  }
  if (a.has("first-temp-id")) {
    if (!ev3io::to_uint(a.get("first-temp-id"), ev3proto::kFirstTempId, 65535, v) || v + o.agents > 65536)
      return "bad value for --first-temp-id: temporary ids N .. N + agents - 1 must lie in 50000..65535";
    o.first_temp_id = static_cast<std::uint16_t>(v);
  }
  o.master_status = a.get("master-status");
  if (a.has("master-pid")) {
    if (!ev3io::to_uint(a.get("master-pid"), 1, 4194304, v)) return "bad value for --master-pid: '" + a.get("master-pid") + "'";
    o.master_pid = static_cast<long>(v);
  }
  if (a.has("report-ms")) {
    if (!ev3io::to_uint(a.get("report-ms"), 1, 60000, v)) return "bad value for --report-ms: '" + a.get("report-ms") + "' (1..60000)";
    o.report_ms = v;
  }
  o.json = a.has("json");
  return {};
}

using AgentCore = ev3proto::Agent<>;

/// One simulated agent: its socket, its core, and what the measurement needs.
struct Sim {
  int fd = -1;
  std::unique_ptr<AgentCore> core;
  Micros ping_at = 0;        // when the last PING's first copy went out
  std::uint32_t ping_id = 0; // its msgid (0: none waiting for a PONG)
  bool synced = false;       // reached ACTIVE at least once
  bool synced_now = false;   // ACTIVE / WORKING / PAUSED now
  unsigned losses = 0;       // HeartbeatLost (synced -> PANIC) in the window
  Millis due = ~Millis{0};   // the core's next deadline, as armed in the heap
  bool working = false;      // WORKING now: makes reports (--report-ms)
};

/// The one behaviour the simulated agents take (`behaviour all wait seconds=N` from the master),
/// so that a START makes them WORKING and they report.
constexpr ev3proto::BehaviourSpec kWaitOnly[] = {{"wait", 0}};

/// A copy to send later.
struct Copy {
  Millis at;
  std::uint64_t seq;
  std::size_t agent;
  std::string bytes;
  bool operator>(const Copy& o) const { return at != o.at ? at > o.at : seq > o.seq; }
};

class LoadGen {
 public:
  explicit LoadGen(const Options& o) : o_(o) {}

  int run() {
    if (!raise_fd_limit()) return 1;
    ep_ = epoll_create1(EPOLL_CLOEXEC);
    if (ep_ < 0) return fail("epoll_create1");
    master_.sin_family = AF_INET;
    master_.sin_addr.s_addr = o_.master.addr;
    master_.sin_port = htons(o_.master.port);
    sims_.resize(o_.agents);
    for (std::size_t i = 0; i < o_.agents; ++i)
      if (!open_socket(i)) return 1;
    const Millis t0 = ms();
    const double ramp_ms = o_.ramp_s * 1000.0;
    std::size_t started = 0;
    Millis window_start = 0, window_end = 0;
    Millis next_report = t0 + 1000, next_status_check = 0;
    bool in_window = false;
    std::fprintf(stderr, "ev3-loadgen: %zu agents -> %s, heartbeat %llu ms, ramp %.1f s\n", o_.agents,
                 o_.master.str().c_str(), static_cast<unsigned long long>(o_.heartbeat), o_.ramp_s);
    std::vector<epoll_event> evs(512);
    std::vector<char> buf(ev3proto::kMaxDatagram + 1);
    while (!g_stop) {
      Millis now = ms();
      // Start the agents whose turn has come (spread over the ramp).
      while (started < o_.agents &&
             (o_.agents == 1 || static_cast<double>(now - t0) >= ramp_ms * static_cast<double>(started) / static_cast<double>(o_.agents - 1))) {
        start_agent(started, now);
        ++started;
      }
      // Deadlines of the agents, then the copies due.
      while (!due_.empty() && due_.top().first <= now) {
        const Due d = due_.top();
        due_.pop();
        Sim& s = sims_[d.second];
        if (s.due != d.first) continue;  // armed again since: a stale item
        s.due = kNever;
        s.core->advance(now);
        drain(d.second, now);
      }
      while (!reports_due_.empty() && reports_due_.top().first <= now) {
        const std::size_t i = reports_due_.top().second;
        reports_due_.pop();
        make_report(i, now);
      }
      flush_copies(now);
      // Phases: settle until all synced, then the window.
      if (!in_window && window_end == 0 && started == o_.agents &&
          ((o_.report_ms != 0 ? working_now_ : synced_now_) == o_.agents ||
           now - t0 >= static_cast<Millis>(o_.settle_s * 1000.0 + ramp_ms))) {
        in_window = true;
        window_start = now;
        window_end = now + static_cast<Millis>(o_.duration_s * 1000.0);
        synced_at_window_ = synced_now_;
        cpu_self_ = self_cpu();
        cpu_master_ = master_cpu();
        std::fprintf(stderr, "ev3-loadgen: %zu of %zu synced after %.1f s; measuring for %.0f s\n", synced_now_,
                     o_.agents, static_cast<double>(now - t0) / 1000.0, o_.duration_s);
      }
      if (in_window && now >= window_end) break;
      if (in_window && !o_.master_status.empty() && now >= next_status_check) {
        status_age();
        next_status_check = now + 100;
      }
      if (now >= next_report) {
        std::fprintf(stderr, "ev3-loadgen: t=%.0fs synced %zu/%zu%s pings %llu pongs %llu losses %llu\n",
                     static_cast<double>(now - t0) / 1000.0, synced_now_, o_.agents, in_window ? " (window)" : "",
                     static_cast<unsigned long long>(pings_), static_cast<unsigned long long>(pongs_),
                     static_cast<unsigned long long>(losses_));
        next_report = now + 1000;
      }
      measuring_ = in_window;
      // Sleep until a datagram, an agent deadline, a copy or the next start.
      while (!due_.empty() && sims_[due_.top().second].due != due_.top().first) due_.pop();
      Millis wake = std::min(due_.empty() ? kNever : due_.top().first, copies_.empty() ? kNever : copies_.top().at);
      if (!reports_due_.empty()) wake = std::min(wake, reports_due_.top().first);
      wake = std::min(wake, next_report);
      if (in_window && !o_.master_status.empty()) wake = std::min(wake, next_status_check);
      if (in_window) wake = std::min(wake, window_end);
      if (started < o_.agents) wake = std::min(wake, now + 1);
      const int timeout = wake <= now ? 0 : static_cast<int>(std::min<Millis>(wake - now, 1000));
      const int n = epoll_wait(ep_, evs.data(), static_cast<int>(evs.size()), timeout);
      if (n < 0 && errno != EINTR) return fail("epoll_wait");
      for (int k = 0; k < n; ++k) receive(static_cast<std::size_t>(evs[static_cast<std::size_t>(k)].data.u64), buf);
    }
    cpu_self_ = self_cpu() - cpu_self_;
    cpu_master_ = master_cpu() - cpu_master_;
    return report(window_start, g_stop ? ms() : window_end);
  }

 private:
  Millis ms() const { return now_us() / 1000u; }

  /// Says what failed (with errno's text); returns 1, the exit status.
  static int fail(const char* what) {
    std::fprintf(stderr, "ev3-loadgen: %s: %s\n", what, std::strerror(errno));
    return 1;
  }

  bool raise_fd_limit() {
    rlimit r{};
    getrlimit(RLIMIT_NOFILE, &r);
    const rlim_t want = static_cast<rlim_t>(o_.agents) + 64;
    if (r.rlim_cur < want) {
      r.rlim_cur = std::min(want, r.rlim_max);
      setrlimit(RLIMIT_NOFILE, &r);
    }
    if (r.rlim_cur < want) {
      std::fprintf(stderr, "ev3-loadgen: %zu agents need %llu file descriptors, the hard limit is %llu (ulimit -Hn)\n",
                   o_.agents, static_cast<unsigned long long>(want), static_cast<unsigned long long>(r.rlim_max));
      return false;
    }
    return true;
  }

  bool open_socket(std::size_t i) {
    const int fd = socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    const char* failed = nullptr;
    sockaddr_in sa{};
    sa.sin_family = AF_INET;
    sa.sin_addr.s_addr = o_.bind_addr;
    epoll_event ev{};
    ev.events = EPOLLIN;
    ev.data.u64 = i;
    if (fd < 0)
      failed = "socket";
    else if (bind(fd, reinterpret_cast<sockaddr*>(&sa), sizeof sa) != 0)
      failed = "bind";
    else if (epoll_ctl(ep_, EPOLL_CTL_ADD, fd, &ev) != 0)
      failed = "epoll_ctl";
    sims_[i].fd = fd;
    if (failed != nullptr) fail(failed);
    return failed == nullptr;
  }

  void start_agent(std::size_t i, Millis now) {
    ev3proto::AgentConfig c;
    c.caps.model = "A";
    c.caps.behaviours = kWaitOnly;
    c.caps.behaviour_count = 1;
    c.timers.set(ev3proto::Timer::heartbeat, o_.heartbeat).set(ev3proto::Timer::loss, o_.loss);
    c.timers.set(ev3proto::Timer::paused, o_.paused).set(ev3proto::Timer::sync, o_.sync);
    c.temp_id = static_cast<std::uint16_t>(o_.first_temp_id + i);
    sims_[i].core = std::make_unique<AgentCore>(c, now);
    arm(i);
  }

  /// One datagram waiting on agent @p i's socket (epoll is level-triggered: it reports the socket
  /// again while more wait, so no recv() is spent on finding the socket empty).
  void receive(std::size_t i, std::vector<char>& buf) {
    Sim& s = sims_[i];
    {
      const ssize_t n = recv(s.fd, buf.data(), buf.size(), 0);
      if (n >= 0 && measuring_) ++received_;
      if (n < 0 || !s.core) return;
      const Micros t = now_us();
      const std::string_view d(buf.data(), static_cast<std::size_t>(n));
      if (s.ping_id != 0 && ev3proto::decode(d, rx_).ok() && rx_.type == ev3proto::MsgType::PONG) {
        const auto ref = rx_.param_u32(0);
        if (ref && *ref == s.ping_id) {
          if (measuring_) latencies_.push_back(static_cast<std::uint32_t>(std::min<Micros>(t - s.ping_at, 0xFFFFFFFFu)));
          if (measuring_) ++pongs_;
          s.ping_id = 0;
        }
      }
      s.core->handle_datagram(d, 1, t / 1000u);
      drain(i, t / 1000u);
    }
  }

  /// Sends what agent @p i's core queued (first copy now, the others later) and reads its events.
  void drain(std::size_t i, Millis now) {
    Sim& s = sims_[i];
    ev3proto::Transmit t;
    while (s.core->poll_transmit(t)) {
      if (ev3proto::decode(t.bytes, rx_).ok() && rx_.type == ev3proto::MsgType::PING) {
        if (measuring_ && s.ping_id != 0) ++unanswered_;  // the previous PING got no PONG in time
        s.ping_id = rx_.msgid;
        s.ping_at = now_us();
        if (measuring_) ++pings_;
      }
      send(s.fd, t.bytes);
      for (unsigned c = 1; c < o_.copies; ++c)
        copies_.push(Copy{now + c * o_.copy_gap, ++seq_, i, std::string(t.bytes)});
    }
    ev3proto::AgentEvent e;
    while (s.core->poll_event(e)) {
      if (e.kind != ev3proto::AgentEvent::Kind::state) continue;
      const bool synced = ev3proto::is_synced(e.state);
      if (synced && !s.synced_now) ++synced_now_;
      if (!synced && s.synced_now) {
        --synced_now_;
        if (e.state == ev3proto::State::PANIC && measuring_) {
          ++losses_;
          if (s.losses++ == 0) ++agents_lost_;
        }
      }
      s.synced_now = synced;
      s.synced = s.synced || synced;
      const bool working = e.state == ev3proto::State::WORKING;
      if (working && !s.working && o_.report_ms != 0)  // spread over the period: agents started together
        reports_due_.push(Due{now + 1 + (i * 7919u) % o_.report_ms, i});
      if (working != s.working) working ? ++working_now_ : --working_now_;
      s.working = working;
    }
    arm(i);
  }

  /// Agent @p i's SENSOR_VALUE report (a distance that changes), and its next one while it works.
  void make_report(std::size_t i, Millis now) {
    Sim& s = sims_[i];
    if (!s.working || !s.core) return;
    char v[12];
    std::snprintf(v, sizeof v, "%u", static_cast<unsigned>((now / o_.report_ms + i) % 256));
    const std::string_view values[1] = {v};
    if (s.core->sensor_report("in4", "US-DIST-CM", values, 1, now) && measuring_) ++reports_;
    drain(i, now);
    reports_due_.push(Due{now + o_.report_ms, i});
  }

  /// Puts agent @p i's next deadline in the heap (unless it is there already).
  void arm(std::size_t i) {
    Sim& s = sims_[i];
    const Millis d = s.core->next_deadline();
    if (d == s.due) return;
    s.due = d;
    if (d != kNever) due_.push(Due{d, i});
  }

  void flush_copies(Millis now) {
    while (!copies_.empty() && copies_.top().at <= now) {
      send(sims_[copies_.top().agent].fd, copies_.top().bytes);
      copies_.pop();
    }
  }

  void send(int fd, std::string_view bytes) {
    if (sendto(fd, bytes.data(), bytes.size(), 0, reinterpret_cast<const sockaddr*>(&master_), sizeof master_) < 0)
      ++send_errors_;
    else if (measuring_)
      ++sent_;
  }

  /// CPU seconds of this process so far.
  static double self_cpu() {
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
           static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec) / 1e6;
  }
  /// CPU seconds of the master so far (utime + stime of /proc/PID/stat; 0 without --master-pid).
  double master_cpu() const {
    if (o_.master_pid == 0) return 0;
    std::ifstream f("/proc/" + std::to_string(o_.master_pid) + "/stat");
    std::string line;
    std::getline(f, line);
    const std::size_t close = line.rfind(')');  // the command name may hold spaces
    if (close == std::string::npos) return 0;
    std::istringstream in(line.substr(close + 2));
    std::string field;
    unsigned long long utime = 0, stime = 0;
    for (int i = 3; i <= 15 && in >> field; ++i) {  // fields 14 and 15: utime, stime (clock ticks)
      if (i == 14) utime = std::stoull(field);
      if (i == 15) stime = std::stoull(field);
    }
    return static_cast<double>(utime + stime) / static_cast<double>(sysconf(_SC_CLK_TCK));
  }

  /// Samples the age of the master's status file (CLOCK_REALTIME against its mtime).
  void status_age() {
    struct stat st {};
    if (stat(o_.master_status.c_str(), &st) != 0) return;
    timespec ts{};
    clock_gettime(CLOCK_REALTIME, &ts);
    const double age = static_cast<double>(ts.tv_sec - st.st_mtim.tv_sec) * 1000.0 +
                       static_cast<double>(ts.tv_nsec - st.st_mtim.tv_nsec) / 1e6;
    status_max_age_ = std::max(status_max_age_, age);
  }

  static double pct(std::vector<std::uint32_t>& v, double p) {
    if (v.empty()) return 0;
    const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(p / 100.0 * static_cast<double>(v.size())));
    std::nth_element(v.begin(), v.begin() + static_cast<long>(k), v.end());
    return v[k] / 1000.0;
  }

  /// The master's status JSON: its agent count and the agents it declared lost (counted by "id").
  void master_view(long& agents, long& lost) const {
    agents = lost = -1;
    if (o_.master_status.empty()) return;
    std::ifstream f(o_.master_status);
    std::stringstream ss;
    ss << f.rdbuf();
    const std::string s = ss.str();
    const std::size_t a = s.find("\"agents\":["), l = s.find("\"lost\":["), d = s.find("\"drops\":");
    if (a == std::string::npos || l == std::string::npos || d == std::string::npos) return;
    auto count = [&](std::size_t from, std::size_t to) {
      long n = 0;
      for (std::size_t p = s.find("{\"id\":", from); p != std::string::npos && p < to; p = s.find("{\"id\":", p + 1)) ++n;
      return n;
    };
    agents = count(a, l);
    lost = count(l, d);
  }

  int report(Millis from, Millis to) {
    const double secs = static_cast<double>(to - from) / 1000.0;
    const std::size_t samples = latencies_.size();
    const double p50 = pct(latencies_, 50), p90 = pct(latencies_, 90), p99 = pct(latencies_, 99),
                 pmax = pct(latencies_, 100);
    long m_agents = -1, m_lost = -1;
    master_view(m_agents, m_lost);
    if (o_.json) {
      std::printf(
          "{\"agents\":%zu,\"heartbeat_ms\":%llu,\"window_s\":%.3f,\"synced_at_start\":%zu,\"synced_at_end\":%zu,"
          "\"agents_lost\":%zu,\"heartbeat_losses\":%llu,\"pings\":%llu,\"pongs\":%llu,\"unanswered\":%llu,"
          "\"pong_ms\":{\"samples\":%zu,\"p50\":%.2f,\"p90\":%.2f,\"p99\":%.2f,\"max\":%.2f},"
          "\"send_errors\":%llu,\"master_agents\":%ld,\"master_lost\":%ld,\"status_max_age_ms\":%.0f,"
          "\"cpu_loadgen\":%.2f,\"cpu_master\":%.4f,\"sent\":%llu,\"received\":%llu,\"reports\":%llu}\n",
          o_.agents, static_cast<unsigned long long>(o_.heartbeat), secs, synced_at_window_, synced_now_, agents_lost_,
          static_cast<unsigned long long>(losses_), static_cast<unsigned long long>(pings_),
          static_cast<unsigned long long>(pongs_), static_cast<unsigned long long>(unanswered_), samples, p50, p90,
          p99, pmax, static_cast<unsigned long long>(send_errors_), m_agents, m_lost, status_max_age_,
          cpu_self_ / secs, o_.master_pid ? cpu_master_ / secs : -1.0, static_cast<unsigned long long>(sent_),
          static_cast<unsigned long long>(received_), static_cast<unsigned long long>(reports_));
    } else {
      std::printf("agents %zu (heartbeat %llu ms), window %.1f s: synced %zu at start, %zu at end; %zu agents lost "
                  "the master (%llu heartbeat losses)\n",
                  o_.agents, static_cast<unsigned long long>(o_.heartbeat), secs, synced_at_window_, synced_now_,
                  agents_lost_, static_cast<unsigned long long>(losses_));
      std::printf("PINGs %llu, PONGs %llu, unanswered %llu; PONG latency ms: p50 %.2f p90 %.2f p99 %.2f max %.2f "
                  "(%zu samples); send errors %llu; datagrams sent %llu, received %llu (copies included)\n",
                  static_cast<unsigned long long>(pings_), static_cast<unsigned long long>(pongs_),
                  static_cast<unsigned long long>(unanswered_), p50, p90, p99, pmax, samples,
                  static_cast<unsigned long long>(send_errors_), static_cast<unsigned long long>(sent_),
                  static_cast<unsigned long long>(received_));
      if (o_.report_ms != 0)
        std::printf("reports made in the window: %llu (one per agent every %llu ms while WORKING)\n",
                    static_cast<unsigned long long>(reports_), static_cast<unsigned long long>(o_.report_ms));
      std::printf("CPU over the window, in cores: ev3-loadgen %.2f", cpu_self_ / secs);
      if (o_.master_pid != 0) std::printf(", master %.2f", cpu_master_ / secs);
      std::printf("\n");
      if (m_agents >= 0)
        std::printf("master: %ld agents registered, %ld declared lost; status file at most %.0f ms old\n", m_agents,
                    m_lost, status_max_age_);
    }
    return 0;
  }

  Options o_;
  int ep_ = -1;
  sockaddr_in master_{};
  std::vector<Sim> sims_;
  using Due = std::pair<Millis, std::size_t>;  // (deadline, agent)
  std::priority_queue<Due, std::vector<Due>, std::greater<Due>> due_;
  std::priority_queue<Due, std::vector<Due>, std::greater<Due>> reports_due_;  // --report-ms: (when, agent)
  std::priority_queue<Copy, std::vector<Copy>, std::greater<Copy>> copies_;
  std::uint64_t seq_ = 0;
  ev3proto::Message rx_;
  bool measuring_ = false;
  std::size_t synced_now_ = 0, synced_at_window_ = 0, agents_lost_ = 0, working_now_ = 0;
  std::uint64_t pings_ = 0, pongs_ = 0, unanswered_ = 0, losses_ = 0, send_errors_ = 0, reports_ = 0;
  std::uint64_t sent_ = 0, received_ = 0;  // datagrams (copies included) sent and received in the window
  std::vector<std::uint32_t> latencies_;  // microseconds
  double status_max_age_ = 0;            // ms
  double cpu_self_ = 0, cpu_master_ = 0; // CPU seconds in the window
};

}  // namespace

int main(int argc, char** argv) {
  Options o;
  bool help = false;
  const std::string err = parse(argc, argv, o, help);
  if (help) {
    std::printf("%s", ev3io::usage(kSynopsis, kSpecs).c_str());
    return 0;
  }
  if (!err.empty()) {
    std::fprintf(stderr, "ev3-loadgen: %s (try --help)\n", err.c_str());
    return 2;
  }
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  static LoadGen g(o);
  return g.run();
}
