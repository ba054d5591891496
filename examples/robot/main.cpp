// minirobot: one robot of the fleet on libev3proto's installed headers alone (docs/embedding.md
// walks through it). The library decides everything: what to send, when, what the robot does and
// what must be on stable storage. This program owns the I/O: one UDP socket, one poll loop, the
// election state in a file, and the brick's status LEDs.
//
//   minirobot [--port N] [--bind ADDR] [--broadcast HOST:PORT] [--state FILE] [--leds DIR]
//             [--timer NAME=MS ...]
//
// It drives no motor and reads no sensor, so it announces no devices and runs the one behaviour of
// model A that needs none: `wait seconds=N`. With ev3dev's LEDs under --leds (on a brick,
// /sys/class/leds) they show the lifecycle. It prints one line per thing that happens.
#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <ev3proto/durable.hpp>
#include <ev3proto/node.hpp>
#include <ev3proto/robot/behaviours.hpp>
#include <ev3proto/robot_link.hpp>

namespace {

namespace robot = ev3proto::robot;
using ev3proto::Durable;
using ev3proto::Millis;
using Node = ev3proto::Node<>;
using Link = robot::RobotLink<Node>;
using K = ev3proto::NodeEvent::Kind;

volatile sig_atomic_t g_signal = 0;

Millis now_ms() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<Millis>(ts.tv_sec) * 1000u + static_cast<Millis>(ts.tv_nsec) / 1000000u;
}

std::string str(std::string_view s) { return std::string(s); }

// Model A's behaviours (robot/behaviours.hpp) as the agent core's table: the name, the devices needed.
constexpr auto kBehaviours = [] {
  std::array<ev3proto::BehaviourSpec, std::size(robot::kModelABehaviours)> t{};
  for (std::size_t i = 0; i < t.size(); ++i)
    t[i] = {robot::kModelABehaviours[i].name, robot::kModelABehaviours[i].devices};
  return t;
}();

// ev3dev's four status LEDs, in the order of robot::led_dev(0..3).
constexpr const char* kLedNames[robot::kLedCount] = {"led0:red:brick-status", "led0:green:brick-status",
                                                     "led1:red:brick-status", "led1:green:brick-status"};

struct Options {
  sockaddr_in bind{};
  sockaddr_in broadcast{};
  std::string state = "minirobot.state";
  std::string leds = "/sys/class/leds";
  ev3proto::Timers timers;
};

bool parse_number(const std::string& s, unsigned long max, unsigned long& v) {
  char* end = nullptr;
  errno = 0;
  v = std::strtoul(s.c_str(), &end, 10);
  return !s.empty() && s[0] >= '0' && s[0] <= '9' && *end == '\0' && errno == 0 && v <= max;
}

// "HOST:PORT" (HOST an IPv4 address) into @p a.
bool parse_endpoint(const std::string& s, sockaddr_in& a) {
  const std::size_t colon = s.rfind(':');
  unsigned long port = 0;
  a.sin_family = AF_INET;
  if (colon == std::string::npos || !parse_number(s.substr(colon + 1), 65535, port) ||
      inet_pton(AF_INET, s.substr(0, colon).c_str(), &a.sin_addr) != 1)
    return false;
  a.sin_port = htons(static_cast<std::uint16_t>(port));
  return true;
}

// ------------------------------------------------------------------------------ the durable state
// What Durable holds (election/common.hpp), as the library writes it and checks it (durable.hpp: the
// key=value lines ev3-agent's state file has too). This program does the I/O: written to FILE.tmp,
// flushed to the disk, renamed over FILE, and the directory flushed: after a crash the file is the
// old state or the new one, never half of each.

std::string members_text(const Durable& d) {
  return std::string(ev3proto::IdListText().ids(d.members, d.member_count).view());
}

bool save_state(const std::string& path, const Durable& d) {
  const ev3proto::DurableText text = ev3proto::durable_text(d);
  const std::string tmp = path + ".tmp";
  const int fd = open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  bool ok = fd >= 0 && write(fd, text.view().data(), text.view().size()) == static_cast<ssize_t>(text.view().size()) &&
            fsync(fd) == 0;
  if (fd >= 0) ok = close(fd) == 0 && ok;
  ok = ok && rename(tmp.c_str(), path.c_str()) == 0;
  const std::size_t slash = path.rfind('/');
  const int dir = open(slash == std::string::npos ? "." : path.substr(0, slash + 1).c_str(), O_RDONLY | O_DIRECTORY);
  if (dir >= 0) {
    ok = fsync(dir) == 0 && ok;
    close(dir);
  }
  return ok;
}

// 1: read into @p d; 0: no file (a robot's first start: the defaults); -1: unreadable, or damaged
// (@p why names the key).
int load_state(const std::string& path, Durable& d, ev3proto::DurableError& why) {
  std::FILE* f = std::fopen(path.c_str(), "r");
  if (f == nullptr) return errno == ENOENT ? 0 : -1;
  std::string text;
  char buf[256];
  for (std::size_t n; (n = std::fread(buf, 1, sizeof buf, f)) > 0;) text.append(buf, n);
  const bool failed = std::ferror(f) != 0;
  std::fclose(f);
  if (failed) return -1;
  return ev3proto::parse_durable(text, d, why) ? 1 : -1;
}

// ------------------------------------------------------------------------------ the robot

class Robot {
 public:
  Robot(const Options& o, const Durable& d, Millis now)
      : opt_(o), rt_(runtime_config(o), now), link_(robot::announced_devices(false)), node_(config(d), now) {}

  int run() {
    fd_ = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
    const int yes = 1;
    if (fd_ < 0 || setsockopt(fd_, SOL_SOCKET, SO_BROADCAST, &yes, sizeof yes) != 0 ||
        bind(fd_, reinterpret_cast<const sockaddr*>(&opt_.bind), sizeof opt_.bind) != 0) {
      std::fprintf(stderr, "minirobot: cannot open the UDP socket: %s\n", std::strerror(errno));
      return 1;
    }
    find_leds();
    rt_.led(node_.agent().led());
    sigset_t waiting;  // the signals are blocked except while the loop waits in ppoll
    sigprocmask(SIG_SETMASK, nullptr, &waiting);
    sigdelset(&waiting, SIGTERM);
    sigdelset(&waiting, SIGINT);
    pump(now_ms());
    while (g_signal == 0 && !failed_) {
      char buf[ev3proto::kMaxDatagram + 1];  // one byte more: a longer datagram is refused, not cut
      sockaddr_in from{};
      for (int i = 0; i < 64; ++i) {  // the datagrams waiting, then time
        socklen_t len = sizeof from;
        const ssize_t n = recvfrom(fd_, buf, sizeof buf, 0, reinterpret_cast<sockaddr*>(&from), &len);
        if (n < 0) break;
        node_.handle_datagram(std::string_view(buf, static_cast<std::size_t>(n)), peer_of(from), now_ms());
        pump(now_ms());
      }
      const Millis now = now_ms();
      if (now >= rt_.next_deadline()) rt_.tick(now);  // a robot with sensors reads them first
      node_.advance(now);
      pump(now);
      const Millis next = std::min(node_.next_deadline(), rt_.next_deadline());
      const Millis wait = next <= now ? 0 : std::min<Millis>(next - now, 1000);
      const timespec ts{static_cast<time_t>(wait / 1000), static_cast<long>(wait % 1000) * 1000000L};
      pollfd p{fd_, POLLIN, 0};
      ppoll(&p, 1, &ts, &waiting);
    }
    if (rt_.busy()) rt_.control(ev3proto::ControlKind::stop, "", nullptr, 0, now_ms());
    rt_.led(ev3proto::Led::DARK);
    write_devices();
    std::printf("stopped%s\n", failed_ ? ": the state file could not be written" : "");
    close(fd_);
    return failed_ ? 1 : 0;
  }

 private:
  /// The runtime's settings: the contact watchdog the library gives the heartbeat (`--timer heartbeat=MS`).
  static robot::RuntimeConfig runtime_config(const Options& o) {
    robot::RuntimeConfig r;
    r.watchdog_ms = robot::watchdog_for(o.timers[ev3proto::Timer::heartbeat]);
    return r;
  }

  Node::Config config(const Durable& d) {
    Node::Config c;
    c.agent.caps = {"A", kBehaviours.data(), kBehaviours.size(), link_.announced(), robot::kModelADeviceNames,
                    std::size(robot::kModelADeviceNames)};
    c.agent.check = robot::behaviour_check(rt_);  // BEHAVIOUR is parsed and checked on receipt
    c.agent.timers = opt_.timers;
    std::uint64_t r = 0;  // the temporary id and the first msgid: drawn by the library from random bits
    const int fd = open("/dev/urandom", O_RDONLY | O_CLOEXEC);
    if (fd < 0 || read(fd, &r, sizeof r) != static_cast<ssize_t>(sizeof r))
      r = now_ms() ^ static_cast<unsigned>(getpid());
    if (fd >= 0) close(fd);
    const ev3proto::StartIds ids = ev3proto::draw_start_ids(r);
    c.agent.temp_id = ids.temp_id;
    c.agent.first_msgid = ids.first_msgid;
    c.agent.election.enabled = true;  // relay and election: a robot may become the fleet's master
    c.agent.election.seed = static_cast<std::uint32_t>(r >> 32) | 1u;  // the back-off's random part
    c.agent.election.durable = d;
    return c;
  }

  // Everything the last call into the node or the runtime gave: node events (a durable change
  // written as it comes) and the runtime's writes, then the node's ready(): whatever durable state is
  // still due on disk first, then the datagrams that call queued. A failed write sends nothing, and
  // the robot stops.
  void pump(Millis now) {
    link_.exchange(
        node_, rt_, now, [this](const ev3proto::NodeEvent& e) { on_event(e); }, [this] { write_devices(); },
        [this](const robot::LinkNote& n) { on_note(n); });
    if (failed_) return;
    failed_ = !node_.ready([this](const Durable& d) { return write_state(d); },
                           [this](const ev3proto::NodeTransmit& t) { send(t); });
    ev3proto::OperatorEvent o;  // the Master core's, while this robot is the elected master
    while (node_.poll_operator_event(o))
      std::printf("master: agent %u %s %s\n", o.agent, str(to_string(o.kind)).c_str(), o.text.c_str());
  }

  bool write_state(const Durable& d) {
    if (!save_state(opt_.state, d)) {
      std::printf("error: cannot write %s: %s; sending nothing more\n", opt_.state.c_str(), std::strerror(errno));
      return false;
    }
    std::printf("durable: epoch %u, voted for %u, members [%s] of epoch %u, floor %u: written to %s\n", d.epoch,
                d.voted_for, members_text(d).c_str(), d.mepoch, d.floor, opt_.state.c_str());
    return true;
  }

  // A datagram to its peer; to everyone when broadcast, or for the master before its address is known.
  void send(const ev3proto::NodeTransmit& t) {
    const sockaddr_in* to = &opt_.broadcast;
    if (t.dest != ev3proto::Dest::broadcast && t.peer >= 1 && t.peer <= peers_.size()) to = &peers_[t.peer - 1];
    else if (t.dest == ev3proto::Dest::peer) return;  // no address: counted by the node (unrouted())
    for (int copy = 0; copy < 3; ++copy)  // 3 copies (docs/protocol.md "Duplicates and stale copies")
      sendto(fd_, t.bytes.data(), t.bytes.size(), 0, reinterpret_cast<const sockaddr*>(to), sizeof *to);
  }

  void on_event(const ev3proto::NodeEvent& e) {
    const auto& a = node_.agent();
    switch (e.kind) {
      case K::state: std::printf("state %s (id %u)\n", str(to_string(e.state)).c_str(), a.id()); break;
      case K::durable:  // written now, so the lines read in order; ready() would write it before sending anyway
        if (!node_.persist([this](const Durable& d) { return write_state(d); })) failed_ = true;
        break;
      case K::role: std::printf("election: role %s in epoch %u\n", str(to_string(e.role)).c_str(), e.epoch); break;
      case K::leader:
        if (e.leader != 0)
          std::printf("following master %u (epoch %u)%s\n", e.leader, e.epoch,
                      e.via != 0 ? (" through agent " + std::to_string(e.via)).c_str() : "");
        break;
      case K::master_started: std::printf("master of epoch %u: running a Master core\n", e.epoch); break;
      case K::master_stopped: std::printf("master of epoch %u: stepped down\n", e.epoch); break;
      default: break;  // led and control are the runtime's (robot_link.hpp); relays
    }
  }

  void on_note(const robot::LinkNote& n) {
    if (n.kind == robot::LinkNote::Kind::control)
      std::printf("behaviour %s: %s\n", str(n.name).c_str(), str(to_string(n.control)).c_str());
    else if (n.kind == robot::LinkNote::Kind::result)
      std::printf("action %s%s%s\n", str(to_string(n.result.outcome)).c_str(), n.result.detail.empty() ? "" : ": ",
                  str(n.result.detail.view()).c_str());
  }

  // The LEDs found under --leds go to the runtime with their max_brightness.
  void find_leds() {
    for (std::size_t i = 0; i < robot::kLedCount; ++i) {
      const std::string dir = opt_.leds + "/" + kLedNames[i] + "/";
      std::FILE* f = std::fopen((dir + "max_brightness").c_str(), "r");
      int max = 0;
      if (f == nullptr) continue;
      if (std::fscanf(f, "%d", &max) == 1 && max > 0) {
        rt_.led_present(robot::led_dev(i), max);
        led_dirs_[i] = dir;
      }
      std::fclose(f);
    }
  }

  // The runtime's device writes: here only LEDs (trigger, delay_on, delay_off, brightness).
  void write_devices() {
    robot::Write w;
    while (rt_.poll_write(w)) {
      if (!robot::is_led(w.dev)) continue;
      const std::string& dir = led_dirs_[robot::index(w.dev) - robot::index(robot::led_dev(0))];
      const std::string file = dir + str(robot::to_string(w.attr));
      const int fd = open(file.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
      if (fd < 0) continue;
      if (write(fd, w.value.view().data(), w.value.view().size()) < 0) std::printf("LED write failed\n");
      close(fd);
    }
  }

  // A small number for each address heard from (0 is "none"): the node names peers by it.
  ev3proto::Peer peer_of(const sockaddr_in& a) {
    for (std::size_t i = 0; i < peers_.size(); ++i)
      if (peers_[i].sin_addr.s_addr == a.sin_addr.s_addr && peers_[i].sin_port == a.sin_port)
        return static_cast<ev3proto::Peer>(i + 1);
    peers_.push_back(a);
    return static_cast<ev3proto::Peer>(peers_.size());
  }

  Options opt_;
  robot::Runtime rt_;
  Link link_;
  Node node_;
  int fd_ = -1;
  bool failed_ = false;
  std::vector<sockaddr_in> peers_;
  std::string led_dirs_[robot::kLedCount];
};

void on_signal(int s) { g_signal = s; }

int usage(const char* bad) {
  if (bad) std::fprintf(stderr, "minirobot: bad argument: %s\n", bad);
  std::fprintf(bad ? stderr : stdout,
               "usage: minirobot [--port N] [--bind ADDR] [--broadcast HOST:PORT] [--state FILE] [--leds DIR]\n"
               "                 [--timer NAME=MS ...]   (NAME: sync, heartbeat, loss, paused, backoff, ...)\n");
  return bad ? 2 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  std::setvbuf(stdout, nullptr, _IOLBF, 0);
  Options o;
  o.bind.sin_family = AF_INET;
  o.bind.sin_port = htons(12345);
  parse_endpoint("255.255.255.255:12345", o.broadcast);
  for (int i = 1; i < argc; ++i) {
    const std::string flag = argv[i];
    if (flag == "--help") return usage(nullptr);
    if (i + 1 == argc) return usage(argv[i]);
    const std::string v = argv[++i];
    unsigned long n = 0;
    const std::size_t eq = v.find('=');
    bool ok = true;
    if (flag == "--port" && parse_number(v, 65535, n)) o.bind.sin_port = htons(static_cast<std::uint16_t>(n));
    else if (flag == "--bind") ok = inet_pton(AF_INET, v.c_str(), &o.bind.sin_addr) == 1;
    else if (flag == "--broadcast") ok = parse_endpoint(v, o.broadcast);
    else if (flag == "--state") o.state = v;
    else if (flag == "--leds") o.leds = v;
    else if (flag == "--timer" && eq != std::string::npos && parse_number(v.substr(eq + 1), 3600000, n)) {
      const auto t = std::find_if(ev3proto::kTimerTable.begin(), ev3proto::kTimerTable.end(),
                                  [&](const ev3proto::TimerSpec& s) { return s.name == v.substr(0, eq); });
      ok = t != ev3proto::kTimerTable.end() && (o.timers.set(t->timer, n), true);
    } else ok = false;
    if (!ok) return usage(argv[i]);
  }
  if (!o.timers.valid()) return usage("--timer: paused must be longer than loss");

  Durable d;
  ev3proto::DurableError why;
  const int loaded = load_state(o.state, d, why);
  if (loaded < 0) {
    std::fprintf(stderr, "minirobot: %s is unreadable or damaged%s%s; not starting with a guessed state\n",
                 o.state.c_str(), why.view().empty() ? "" : ": ", std::string(why.view()).c_str());
    return 2;
  }
  std::printf("minirobot: port %u, state %s: %s epoch %u, voted for %u, members [%s] of epoch %u, floor %u\n",
              ntohs(o.bind.sin_port), o.state.c_str(), loaded ? "read back:" : "none yet, starting in", d.epoch,
              d.voted_for, members_text(d).c_str(), d.mepoch, d.floor);
  sigset_t block;  // SIGTERM and SIGINT only interrupt the loop's wait (no lost wake-up)
  sigemptyset(&block);
  sigaddset(&block, SIGTERM);
  sigaddset(&block, SIGINT);
  sigprocmask(SIG_BLOCK, &block, nullptr);
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGINT, &sa, nullptr);
  auto r = std::make_unique<Robot>(o, d, now_ms());  // the node is large (84 KiB on armel): not on the stack
  return r->run();
}
