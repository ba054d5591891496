// ev3-agent: one robot of the fleet. The I/O around the robot node (libev3proto node.hpp: the agent
// core, and the Master core it runs while elected) and the robot runtime (robot_runtime.hpp: model
// A's devices, actions, events, LEDs), linked by robot_link.hpp: a UDP socket, ev3dev's sysfs
// through the device layer (io/ev3io/devices.hpp, robot_io.hpp), one event loop (ppoll) that sleeps
// until the next datagram or the earliest deadline (node, runtime tick, device scan, copy sends,
// log flush), logging and the NDJSON trace. Every decision is the library's; this program turns
// inputs and outputs into I/O, logs what they report, and with --election keeps the election state
// on disk (--state-dir). docs/programs.md describes the command line, docs/devices.md the loop.
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <optional>
#include <cstring>
#include <map>
#include <string>
#include <vector>

#include <ev3proto/durable.hpp>
#include <ev3proto/node.hpp>
#include <ev3proto/robot/behaviours.hpp>
#include <ev3proto/robot_link.hpp>
#include <ev3proto/trace.hpp>
#include <ev3proto/wire.hpp>

#include "ev3prog/console.hpp"
#include "ev3prog/program.hpp"
#include "ev3prog/script.hpp"
#include "ev3prog/trace_file.hpp"
#include "ev3io/devices.hpp"
#include "ev3io/log.hpp"
#include "ev3io/loop.hpp"
#include "ev3io/robot_io.hpp"
#include "ev3io/udp.hpp"
#include "agent_options.hpp"
#include "agent_sink.hpp"
#include "driver.hpp"

namespace {

using namespace ev3io::levels;
using ev3proto::Millis;

namespace robot = ev3proto::robot;

// The agent core's table of model A's built-in behaviours (robot/behaviours.hpp).
constexpr ev3proto::BehaviourSpec kModelABehaviours[] = {
    {robot::kModelABehaviours[0].name, robot::kModelABehaviours[0].devices},
    {robot::kModelABehaviours[1].name, robot::kModelABehaviours[1].devices},
    {robot::kModelABehaviours[2].name, robot::kModelABehaviours[2].devices},
    {robot::kModelABehaviours[3].name, robot::kModelABehaviours[3].devices},
    {robot::kModelABehaviours[4].name, robot::kModelABehaviours[4].devices},
};
static_assert(std::size(robot::kModelABehaviours) == std::size(kModelABehaviours));

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

using ev3agent::RobotNode;
using Link = robot::RobotLink<RobotNode>;

/// Device bits as role names ("left,right").
std::string roles(std::uint32_t bits) {
  std::string s;
  for (std::size_t i = 0; i < robot::kRoleCount; ++i)
    if ((bits & robot::role_bit(static_cast<robot::Role>(i))) != 0)
      s += (s.empty() ? "" : ",") + std::string(robot::to_string(static_cast<robot::Role>(i)));
  return s.empty() ? "none" : s;
}

std::string role_name(ev3proto::ElectionRole r) {
  switch (r) {
    case ev3proto::ElectionRole::none: return "follower";
    case ev3proto::ElectionRole::candidate: return "CANDIDATE";
    case ev3proto::ElectionRole::master: return "MASTER";
  }
  return "?";
}

class Program {
 public:
  explicit Program(const ev3agent::AgentOptions& o)
      : opt_(o), sh_("ev3-agent", o.common.faults), devices_(o.sysfs_root), rio_(devices_) {}

  int run() {
    if (const int rc = sh_.open("agent", opt_.common)) return rc;
    if (sh_.trace_file.is_open()) trace_.ndjson = sh_.trace_file.output();
    // The robot: the runtime of model A and the device layer's first scan (what is found decides
    // what the agent announces: robot_link.hpp announced_devices).
    const Millis start = ev3io::monotonic_ms();
    robot::RuntimeConfig rc;
    rc.ports = opt_.ports;
    rc.tick_ms = opt_.tick_ms;
    rc.watchdog_ms = opt_.watchdog_ms;
    rc.start_pose = opt_.pose;
    rc.pose_ms = opt_.pose_ms;
    rt_.emplace(rc, start);
    rio_.scan(*rt_, start);
    link_.emplace(robot::announced_devices(devices_.ev3dev_tree()));
    ev3proto::AgentConfig cfg;
    cfg.caps = {opt_.model, kModelABehaviours, std::size(kModelABehaviours), link_->announced(),
                robot::kModelADeviceNames, std::size(robot::kModelADeviceNames)};
    cfg.check = robot::behaviour_check(*rt_);
    cfg.timers = opt_.timers;
    cfg.report_limit = opt_.report_buffer;
    const ev3proto::StartIds ids = ev3proto::draw_start_ids(random_u64());
    cfg.temp_id = ids.temp_id;
    cfg.first_msgid = ids.first_msgid;
    cfg.election.enabled = opt_.election;
    cfg.election.seed = static_cast<std::uint32_t>(random_u64()) | 1u;  // the back-off's random part
    if (opt_.election) cfg.election.score = opt_.score;
    if (!load_state(cfg.election)) return 2;
    if (!sh_.load_script("--master-script", opt_.master_script)) return 2;
    if (opt_.model != "A")
      sh_.log.log(kInfo, "model %s: using model A's capability table and devices", opt_.model.c_str());
    const Millis now = ev3io::monotonic_ms();
    RobotNode::Config nc;
    nc.agent = cfg;
    if (sh_.trace_file.is_open()) {
      // The Master core's records go to the same file, node "master:ID:EPOCH" (one Master core per
      // epoch won; docs/spec.md "Election master traces").
      nc.master_trace = [this](std::uint16_t id, std::uint32_t epoch) {
        mtrace_.emplace("master:" + std::to_string(id) + ":" + std::to_string(epoch));
        mtrace_->set_output(sh_.trace_file.output());
        return &*mtrace_;
      };
    }
    node_.emplace(nc, now, sh_.trace_file.is_open() ? &trace_ : nullptr);
    log_devices();
    rt_->led(node_->agent().led());
    pump(now);
    std::string bc;
    for (const auto& e : opt_.common.broadcast) bc += " " + e.str();
    sh_.log.log(kInfo, "listening on %s (model %s, temporary id %u, broadcast to%s)", sh_.net.local().str().c_str(),
             opt_.model.c_str(), cfg.temp_id, bc.c_str());
    if (opt_.election)
      sh_.log.log(kInfo, "election on: score %u, epoch %u, voted for %u, state %s", node_->agent().score(),
               cfg.election.durable.epoch, cfg.election.durable.voted_for,
               state_path_.empty() ? "in memory only (no --state-dir)" : state_path_.c_str());
    sh_.log.log(kInfo, "state IDLE");
    sh_.log.flush();
    loop();
    shutdown();
    return sh_.state_failed ? 1 : 0;
  }

  /// What the device layer found at start (and the LEDs / battery), for the log.
  void log_devices() {
    if (!devices_.ev3dev_tree()) {
      sh_.log.log(kInfo, "no ev3dev devices under %s (no class/tacho-motor, class/lego-sensor): no robot body, "
               "announcing no devices (only 'wait' can run)", opt_.sysfs_root.c_str());
      return;
    }
    std::string found;
    for (std::size_t i = 0; i < robot::kRoleCount; ++i) {
      const auto r = static_cast<robot::Role>(i);
      const robot::Dev d = opt_.ports.of(r);
      found += " " + std::string(robot::to_string(r)) + "=" + std::string(robot::to_string(d)) +
               (devices_.present(d) ? "" : "(missing)");
    }
    const std::string watchdog =
        opt_.watchdog_ms == 0 ? "off" : std::to_string(static_cast<unsigned long long>(opt_.watchdog_ms)) + " ms";
    sh_.log.log(kInfo, "devices under %s:%s; LEDs: %s; battery: %s; control tick %llu ms; watchdog %s",
             opt_.sysfs_root.c_str(), found.c_str(), *devices_.led_names() != '\0' ? devices_.led_names() : "none",
             devices_.has_battery() ? "yes" : "no", static_cast<unsigned long long>(opt_.tick_ms), watchdog.c_str());
  }

  /// What the link handed between node and runtime, for the log.
  void on_note(const robot::LinkNote& n) {
    using K = robot::LinkNote::Kind;
    switch (n.kind) {
      case K::result: {
        const char* what = n.result.outcome == robot::Outcome::finished      ? "finished: ACTION_OK"
                           : n.result.outcome == robot::Outcome::interrupted ? "interrupted: ACTION_INTERR"
                                                                             : "failed: ACTION_ERR";
        sh_.log.log(n.result.outcome == robot::Outcome::failed ? kError : kInfo, "action %s%s%s%s%s", what,
                 n.result.outcome == robot::Outcome::interrupted ? " " : "",
                 n.result.outcome == robot::Outcome::interrupted
                     ? std::string(ev3proto::to_string(n.result.warning)).c_str() : "",
                 n.result.detail.empty() ? "" : " - ", std::string(n.result.detail.view()).c_str());
        if (!n.taken) sh_.log.log(kVerbose, "action result not taken by the core (not running)");
        break;
      }
      case K::event: {
        std::string_view p[3];
        const std::size_t c = n.event.params(p);
        std::string text;
        for (std::size_t i = 0; i < c; ++i) text += (i ? " " : "") + std::string(p[i]);
        sh_.log.log(n.event.severity() == robot::Severity::critical ? kInfo : kVerbose, "event %s%s", text.c_str(),
                 n.taken ? " (core: EVENT to the master)" : "");
        break;
      }
      case K::report:
        sh_.log.log(kVerbose, "sensor report %s %s%s", std::string(robot::report_port(n.report)).c_str(),
                 std::string(n.report.mode.view()).c_str(), n.taken ? "" : " (not taken: not running)");
        break;
      case K::missing:
        sh_.log.log(kInfo, "model A devices missing: %s (core: EVENT DEVICE_DISCONNECTED to the master; "
                 "BEHAVIOUR refused until all are plugged)", roles(n.bits).c_str());
        break;
      case K::control:
        sh_.log.log(kDebug, "runtime: %s %s", std::string(ev3proto::to_string(n.control)).c_str(),
                 std::string(n.name).c_str());
        break;
      case K::watchdog:
        if (n.taken)
          sh_.log.log(kInfo, "watchdog: wheels held, no contact with a master for %llu ms",
                   static_cast<unsigned long long>(opt_.watchdog_ms));
        else
          sh_.log.log(kInfo, "watchdog: hold ended (contact with a master, or the core took over)");
        break;
    }
  }

 private:
  void loop() {
    Millis next_summary = ev3io::monotonic_ms() + 5000;
    while (sh_.running()) {
      // At most Shell::kBatch datagrams, then the device scan, the robot's tick, the node's
      // deadlines and the copies due.
      const bool more = sh_.receive([this](const std::string& d, const ev3io::Endpoint& from, Millis now) {
        on_datagram(d, from, now);
      });
      Millis now = ev3io::monotonic_ms();
      if (now >= rio_.next_scan()) {
        rio_.scan(*rt_, now);
        pump(now);
      }
      if (now >= rt_->next_deadline()) {
        rio_.tick(*rt_, now);
        pump(now);
      }
      now = ev3io::monotonic_ms();
      node_->advance(now);
      pump(now);
      if (Link::shut_down(*node_, *rt_)) {
        sh_.log.log(kInfo, "battery low: EVENT BATTERY_LOW sent, motors stopped; exiting");
        battery_exit_ = true;
        break;
      }
      run_script(now);
      sh_.net.flush(now);
      if (now >= next_summary) {
        if (drops_changed_) sh_.log.log(kVerbose, "drops: %s", sh_.drops_line().c_str());
        drops_changed_ = false;
        next_summary = now + 5000;
      }
      Millis deadline = std::min({node_->next_deadline(), rt_->next_deadline(), rio_.next_scan(), next_summary});
      if (node_->master() != nullptr) deadline = std::min(deadline, sh_.script.deadline());
      sh_.wait(now, deadline, more);
    }
  }

  void drop(const std::string& why, std::string_view d) {
    sh_.drop(why, d);
    drops_changed_ = true;
  }

  /// The node takes the datagram; the program only logs and counts what it reports.
  void on_datagram(const std::string& d, const ev3io::Endpoint& from, Millis now) {
    const ev3proto::NodeHandled h = node_->handle_datagram(d, sh_.net.peer_of(from), now);
    const ev3proto::Ignored why = h.why();
    if (why == ev3proto::Ignored::undecodable) {
      drop(ev3prog::decode_drop_key(h.agent.decode.reason), d);
    } else {
      sh_.log.log(kDebug, "recv %s from %s", ev3prog::printable(d).c_str(), from.str().c_str());
      if (why != ev3proto::Ignored::no) {
        drop(std::string(ev3proto::to_string(why)), d);
      } else if (h.agent.action == ev3proto::Action::RecvDuplicate) {
        sh_.count("duplicate_answered_again");
        sh_.log.log(kDebug, "duplicate %s answered again", ev3prog::printable(d).c_str());
      }
    }
    pump(now);
  }

  /// Drains the node's and the runtime's outputs after every call into either: node events (the
  /// LED pattern and behaviour controls to the runtime, its device writes made, its results /
  /// events / reports to the node: robot_link.hpp exchange), then the node's ready(): the durable
  /// state written, then the datagrams. A failed write stops the agent: nothing more is sent (a
  /// VOTE must not go out without its votedFor on disk).
  void pump(Millis now) {
    link_->exchange(
        *node_, *rt_, now, [this, now](const ev3proto::NodeEvent& e) { on_event(e, now); },
        [this, now] { rio_.flush(*rt_, now); }, [this](const robot::LinkNote& n) { on_note(n); });
    if (sh_.state_failed) return;
    sh_.state_failed = !node_->ready([this](const ev3proto::Durable& d) { return save_state(d); },
                                  [this, now](const ev3proto::NodeTransmit& t) { send(t, now); });
    if (sh_.state_failed) return;
    ev3proto::OperatorEvent oe;
    std::vector<ev3prog::FleetView::RuleCommand> ruled;
    while (node_->poll_operator_event(oe)) {
      const std::string addr = ev3prog::agent_address(node_->master()->registry(), oe.agent, sh_.net);
      sh_.log.log(kInfo, "master: %s", view_.on_event(oe, addr, now).c_str());
      if (auto r = view_.follow_rules(oe, node_->master()->registry())) ruled.push_back(std::move(*r));
    }
    for (const ev3prog::FleetView::RuleCommand& r : ruled) {
      sh_.log.log(kInfo, "master: %s", r.say.c_str());
      node_->command(r.agent, r.command, now);
    }
    if (!ruled.empty()) pump(now);
  }

  /// One datagram of the node's: to its peer's address; one for the master whose address is not
  /// known yet to everyone (the node counts those: unrouted()).
  void send(const ev3proto::NodeTransmit& t, Millis now) {
    sh_.log.log(kDebug, "%ssend %s to %s", t.from_master_core ? "master core: " : "", ev3prog::printable(t.bytes).c_str(),
             std::string(to_string(t.dest)).c_str());
    if (t.dest == ev3proto::Dest::broadcast) {
      broadcast(t.bytes, now);
      return;
    }
    const ev3io::Endpoint* ep = sh_.net.endpoint_of(t.peer);
    if (ep != nullptr) {
      sh_.net.send(*ep, t.bytes, now);
    } else if (t.dest == ev3proto::Dest::master) {
      broadcast(t.bytes, now);
    } else {
      drop("unknown_peer", t.bytes);
    }
  }

  void on_event(const ev3proto::NodeEvent& e, Millis now) {
    const ev3agent::AgentCore& a = node_->agent();
    using K = ev3proto::NodeEvent::Kind;
    // Without --election the master followed is always the PC: nothing to say about roles.
    if (!opt_.election && (e.kind == K::role || e.kind == K::leader || e.kind == K::relays)) return;
    switch (e.kind) {
      case K::state: sh_.log.log(kInfo, "state %s (id %u)", std::string(to_string(e.state)).c_str(), a.id()); break;
      case K::led:
      case K::control: break;  // the runtime's (robot_link.hpp)
      case K::durable:  // written by ready() (pump)
        if (e.durable.epoch != e.previous.epoch)
          sh_.log.log(kInfo, "epoch %u (was %u)", e.durable.epoch, e.previous.epoch);
        break;
      case K::role:
        if (e.role == ev3proto::ElectionRole::candidate)
          sh_.log.log(kInfo, "election: standing as CANDIDATE in epoch %u (score %u)", e.epoch, a.score());
        else if (e.role == ev3proto::ElectionRole::master)
          sh_.log.log(kInfo, "election: won epoch %u (score %u): role MASTER", e.epoch, a.score());
        else
          sh_.log.log(kInfo, "election: role %s", role_name(e.role).c_str());
        break;
      case K::leader:
        if (e.leader != 0 && e.via != 0)
          sh_.log.log(kInfo, "following master %u (epoch %u) through the relay of agent %u", e.leader, a.election().epoch, e.via);
        else if (e.leader != 0)
          sh_.log.log(kInfo, "following master %u (epoch %u) directly", e.leader, a.election().epoch);
        break;
      case K::relays: {
        std::string relays;
        const auto& el = a.election();
        for (std::size_t i = 0; i < el.relays.size(); ++i) relays += " " + std::to_string(el.relays.id(i));
        sh_.log.log(kInfo, "relaying for agents:%s", relays.empty() ? " none" : relays.c_str());
        break;
      }
      case K::master_started: {
        std::string m;
        for (std::size_t i = 0; i < a.election().members.size(); ++i) m += " " + std::to_string(a.election().members[i]);
        sh_.log.log(kInfo, "master of epoch %u as id %u: running a Master core (members%s)%s", e.epoch, a.id(),
                 m.c_str(), sh_.script.empty() ? "" : "; running --master-script");
        sh_.script.start(now);
        break;
      }
      case K::master_stopped:
        sh_.log.log(kInfo, "master of epoch %u stepped down (epoch %u is newer)%s; Master core dropped", e.epoch,
                 a.election().epoch, e.handed_over ? " (HANDOVER sent to the new master)" : "");
        break;
    }
  }

  void shutdown() {
    const Millis now = ev3io::monotonic_ms();
    if (rt_->busy()) {
      rt_->control(ev3proto::ControlKind::stop, "", nullptr, 0, now);
      sh_.log.log(kInfo, "behaviour stopped, motors stopped");
    }
    // The node's EVENT(LEAVING) tells the master (no leave message in the protocol); not after a
    // failed state write: nothing is sent then.
    if (!sh_.state_failed && node_->leaving(now)) {
      bool sent = false;
      node_->ready([this](const ev3proto::Durable& d) { return save_state(d); },
                   [this, now, &sent](const ev3proto::NodeTransmit& t) {
                     send(t, now);
                     sent = true;
                   });
      if (sent) sh_.log.log(kInfo, "told the master: EVENT LEAVING");
    }
    sh_.log_stop(battery_exit_ ? "battery low" : nullptr);
    const auto& u = node_->unrouted();
    sh_.log.log(kInfo, "unrouted: %u for the master before its address was known (broadcast), %u for a peer with no "
             "address (dropped)", u.to_master, u.to_peer);
    rt_->led(ev3proto::Led::DARK);
    rio_.flush(*rt_, now);
    const ev3io::RobotIo::Stats& st = rio_.stats();
    sh_.log.log(kInfo, "devices: %zu reads, %zu writes, %zu failed reads, %zu failed writes, %zu unplugs seen",
             st.reads, st.writes, st.failed_reads, st.failed_writes, st.unplugged);
    sh_.close();
  }

  void broadcast(std::string_view bytes, Millis now) {
    for (const auto& b : opt_.common.broadcast) sh_.net.send(b, bytes, now);
  }

  // ------------------------------------------------------------------ relay and election
  /// The election state file: DIR/ev3-agent.state (epoch, voted_for, and the membership the agent
  /// knows: members, members_epoch, floor; a file without those three keys knows no membership),
  /// read and checked by the library's rule (ev3proto/durable.hpp); none without --state-dir.
  bool load_state(ev3proto::ElectionConfig& e) {
    if (opt_.state_dir.empty()) return true;
    state_path_ = opt_.state_dir + "/ev3-agent.state";
    std::optional<std::string> text;
    if (!sh_.read_state("--state-dir", state_path_, text)) return false;
    ev3proto::DurableError why;
    if (text && !ev3proto::parse_durable(*text, e.durable, why)) return sh_.damaged("--state-dir", state_path_, why.view());
    return true;
  }

  /// Writes the election state (epoch, voted_for, the membership) the node's ready() hands over;
  /// false when it is not on disk (then the agent sends nothing more and exits with status 1).
  bool save_state(const ev3proto::Durable& d) {
    const std::string members(ev3proto::IdListText().ids(d.members, d.member_count).view());
    sh_.log.log(kDebug, "durable: epoch %u, voted for %u, members [%s] of epoch %u, floor %u", d.epoch, d.voted_for,
             members.c_str(), d.mepoch, d.floor);
    return sh_.save_state("the election state", state_path_, ev3proto::durable_text(d).view());
  }

  /// --master-script: console commands for the Master core, from the moment this agent won.
  void run_script(Millis now) {
    std::string line;
    while (node_->master() != nullptr && node_->master()->role() == ev3proto::MasterRole::master &&
           sh_.script.next(now, line)) {
      ev3prog::ConsoleCommand c;
      const std::string err = ev3prog::console_command(line, c);
      using K = ev3prog::ConsoleCommand::Kind;
      if (!err.empty()) {
        sh_.log.log(kError, "master script: %s", err.c_str());
      } else if (c.kind == K::send) {
        sh_.log.log(kInfo, "master script> %s", line.c_str());
        node_->command(c.agent, c.command, now);
        pump(now);
      } else if (c.kind == K::rule) {
        sh_.log.log(kInfo, "master script: %s", view_.set_rule(c).c_str());
      } else if (c.kind == K::list) {
        for (const std::string& l : view_.table(node_->master()->registry(), sh_.drops, now, node_->master()->report_records()))
          sh_.log.log(kInfo, "master: %s", l.c_str());
      }
    }
  }

  ev3agent::AgentOptions opt_;
  ev3prog::Shell sh_;  // log, signals, socket, trace file, script, drop counters, state-file writes
  ev3agent::AgentSink trace_;  // the agent core's records (--trace)
  std::optional<RobotNode> node_;
  ev3io::Ev3Devices devices_;
  ev3io::RobotIo rio_;
  std::optional<robot::Runtime> rt_;
  std::optional<Link> link_;
  bool battery_exit_ = false;
  bool drops_changed_ = false;
  // election
  std::string state_path_;
  std::optional<ev3proto::NdjsonTrace> mtrace_;  // the Master core's records (--trace)
  ev3prog::FleetView view_;
};

}  // namespace

int main(int argc, char** argv) {
  return ev3prog::program_main<Program>(argc, argv, "ev3-agent", ev3agent::run_driver, ev3agent::parse_agent_options);
}
