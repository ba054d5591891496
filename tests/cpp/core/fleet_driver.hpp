// Drives several nodes over a scripted network from transcript commands (tests/cpp/testdata/
// fleet_*.txt), as etcd raft's interaction tests do: a PC master and robot nodes (node.hpp: the
// agent core and the Master core it runs when elected). Nothing is delivered unless a command says
// so; every datagram, action and event is printed symbolically.
//
// Inputs:
//   pc [election=1] [resend=ms] [drop=ms] [heartbeat=ms] [candidate=ms]   the PC master (peer 1)
//   agents N [election=1] [scores=S1,S2,...] [sync= heartbeat= loss= paused= relay_retry=
//            backoff= backoff_step= candidate= (ms)]   robot nodes a1..aN (peers 2.., temporary
//                                                      ids 50001..), created at the current time
//   tick MS                  time moves MS for every node; what each does is printed
//   deliver [from=X] [to=Y] [type=T]   delivers the datagrams in flight (matching), once, in order;
//                            what they cause goes in flight behind them
//   drop [from=X] [to=Y] [type=T]      loses the datagrams in flight (matching; prints how many)
//   dup [from=X] [to=Y] [type=T]       a copy of each (matching) goes in flight too
//   stabilize                delivers until nothing is in flight (time stands still)
//   run MS                   time moves MS, every datagram delivered at once (a perfect network);
//                            prints nothing (show what it led to with `show`)
//   cut X Y | partition X... | heal     links: cut one, cut X... from the rest, heal them all
//   cmd [at=X] ID|all|aK start|stop|pause|resume|standby|continue|restart|assign NAME [ARG...]
//                            an operator command at the PC (or at node X's Master core)
//   event X action_ok|action_failed|obstacle|battery_low|unplug BITS PORT|plug BITS PORT
//   crash pc | restart pc    the PC stops; it comes back as a candidate with its epoch, members,
//                            ids and msgids (stable storage)
//   show                     one line per node
// Outputs: `> X <- DATAGRAM` for a delivery (`> X tick` for time), then, indented, each action of
// X (`master: ACTION` for a Master core) followed by what it did: `send Y|all DATAGRAM`, `state`,
// `led`, `control`, `op` (operator events); `Ignore: REASON` for a datagram nothing took; then the
// node's events (durable, role, leader, relays, master_started, master_stopped). `in flight: N`
// closes each case.
#pragma once

#include <algorithm>
#include <deque>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "fixed_timers.hpp"
#include "ev3proto/master.hpp"
#include "ev3proto/node.hpp"
#include "master_driver.hpp"
#include "symbolic.hpp"

namespace ev3test {

using namespace ev3proto;

class FleetDriver;

/// Agent core sink of robot node @c node.
struct FleetAgentSink {
  static constexpr bool enabled = true;
  FleetDriver* driver = nullptr;
  std::size_t node = 0;
  template <typename A>
  void record(const AgentTraceRecord& r, const A&);
};
/// Master core sink of robot node @c node (or the PC: node 0).
struct FleetMasterSink {
  static constexpr bool enabled = true;
  FleetDriver* driver = nullptr;
  std::size_t node = 0;
  void record(const MasterTraceRecord& r);
};

class FleetDriver {
 public:
  using Robot = Node<FleetAgentSink, FleetMasterSink>;
  using Pc = Master<FleetMasterSink>;
  static constexpr Peer kPcPeer = 1;

  std::vector<std::string> run(const std::vector<std::string>& input) {
    lines_.clear();
    for (const std::string& line : input) step(line);
    lines_.push_back("in flight: " + std::to_string(flight_.size()));
    return std::move(lines_);
  }

  /// An agent core of node @p i took action @p r: its line, then what it queued.
  void on_agent(std::size_t i, const AgentTraceRecord& r) {
    std::vector<std::string> out = drain(i);
    if (r.action == Action::Tick && out.empty()) return;
    std::string name(to_string(r.action));
    if (r.action == Action::ApplyCommand) name += ": " + std::string(to_string(r.cmd));
    block(i).push_back("  " + name);
    for (auto& l : out) block(i).push_back("    " + l);
  }
  /// A Master core of node @p i (0: the PC) took action @p r.
  void on_master(std::size_t i, const MasterTraceRecord& r) {
    std::vector<std::string> out = drain(i);
    if (r.action == Action::MasterTick && out.empty()) return;
    block(i).push_back(std::string(i == 0 ? "  " : "  master: ") + std::string(to_string(r.action)));
    for (auto& l : out) block(i).push_back("    " + l);
  }

 private:
  struct Member {
    FleetAgentSink asink;
    FleetMasterSink msink;
    std::unique_ptr<Robot> node;
  };
  struct Flight {
    std::size_t from = 0, to = 0;  // node indexes (0: the PC)
    std::string bytes;
  };

  // ------------------------------------------------------------------ commands

  void step(const std::string& line) {
    std::istringstream in(line);
    std::vector<std::string> w;
    for (std::string s; in >> s;) w.push_back(s);
    if (w.empty()) return;
    const std::string& c = w[0];
    if (c == "pc") make_pc(w);
    else if (c == "agents" && w.size() >= 2) make_agents(w);
    else if (c == "tick" && w.size() == 2) tick(std::stoull(w[1]));
    else if (c == "deliver") deliver(filter(w), true);
    else if (c == "drop") drop(filter(w));
    else if (c == "dup") dup(filter(w));
    else if (c == "stabilize") stabilize(true);
    else if (c == "run" && w.size() == 2) run_for(std::stoull(w[1]));
    else if (c == "cut" && w.size() == 3) cut(node_of(w[1]), node_of(w[2]));
    else if (c == "partition") partition(w);
    else if (c == "heal") down_.clear();
    else if (c == "cmd") command(w, line);
    else if (c == "event" && w.size() >= 3) event(w);
    else if (c == "crash" && w.size() == 2 && w[1] == "pc") crash_pc();
    else if (c == "restart" && w.size() == 2 && w[1] == "pc") restart_pc();
    else if (c == "show") show();
    else lines_.push_back("error: bad input: " + line);
    flush_blocks();
  }

  void make_pc(const std::vector<std::string>& w) {
    MasterConfig c;
    c.timers = ev3test::fixed_timers();
    for (std::size_t i = 1; i < w.size(); ++i) {
      const auto [k, v] = kv(w[i]);
      if (k == "election") c.election = v == "1";
      else if (k == "resend") c.timers.set(Timer::resend, std::stoull(v));
      else if (k == "drop") c.timers.set(Timer::drop, std::stoull(v));
      else if (k == "heartbeat") c.timers.set(Timer::leader_heartbeat, std::stoull(v));
      else if (k == "candidate") c.timers.set(Timer::candidate, std::stoull(v));
      else lines_.push_back("error: bad pc option " + w[i]);
    }
    pc_cfg_ = c;
    pc_sink_ = FleetMasterSink{this, 0};
    pc_ = std::make_unique<Pc>(c, now_, &pc_sink_);
    settle(0);
  }

  void make_agents(const std::vector<std::string>& w) {
    const std::size_t n = std::stoul(w[1]);
    AgentConfig c;
    c.timers = ev3test::fixed_timers();
    c.caps = Capabilities{"A", kBehaviours, 1, 1u};
    std::vector<std::uint32_t> scores;
    for (std::size_t i = 2; i < w.size(); ++i) {
      const auto [k, v] = kv(w[i]);
      if (k == "election") c.election.enabled = v == "1";
      else if (k == "scores") {
        std::istringstream s(v);
        for (std::string x; std::getline(s, x, ',');) scores.push_back(static_cast<std::uint32_t>(std::stoul(x)));
      } else if (!set_timer(c.timers, k, v)) {
        lines_.push_back("error: bad agents option " + w[i]);
      }
    }
    for (std::size_t k = 0; k < n; ++k) {
      const std::size_t i = robots_.size() + 1;
      c.temp_id = static_cast<std::uint16_t>(50000 + i);
      if (k < scores.size()) c.election.score = scores[k];
      auto r = std::make_unique<Member>();
      r->asink = FleetAgentSink{this, i};
      r->msink = FleetMasterSink{this, i};
      Robot::Config rc{c, {}};
      rc.durable_first = false;  // drained inside the trace hooks, before the node reports a durable change
      FleetMasterSink* ms = &r->msink;
      rc.master_trace = [ms](std::uint16_t, std::uint32_t) { return ms; };
      r->node = std::make_unique<Robot>(rc, now_, &r->asink);
      robots_.push_back(std::move(r));
    }
  }

  void tick(Millis ms) {
    now_ += ms;
    advance_all(true);
  }

  void run_for(Millis ms) {
    const Millis until = now_ + ms;
    quiet_ = true;
    stabilize(false);
    while (now_ < until) {
      Millis next = until;
      if (pc_) next = std::min(next, pc_->next_deadline());
      for (auto& r : robots_) next = std::min(next, r->node->next_deadline());
      now_ = std::max(next, now_);
      advance_all(false);
      stabilize(false);
    }
    quiet_ = false;
    blocks_.clear();
  }

  void advance_all(bool print) {
    if (pc_) {
      open_block(0, "> pc tick");
      pc_->advance(now_);
      settle(0);
    }
    for (std::size_t i = 1; i <= robots_.size(); ++i) {
      open_block(i, "> " + name(i) + " tick");
      robots_[i - 1]->node->advance(now_);
      settle(i);
    }
    if (!print) blocks_.clear();
  }

  struct Filter {
    std::size_t from = kAny, to = kAny;
    std::string type;
    bool matches(const Flight& f) const {
      if (from != kAny && f.from != from) return false;
      if (to != kAny && f.to != to) return false;
      if (type.empty()) return true;
      Message m;
      return decode(f.bytes, m).ok() && to_string(m.type) == type;
    }
  };
  static constexpr std::size_t kAny = ~std::size_t{0};

  Filter filter(const std::vector<std::string>& w) {
    Filter f;
    for (std::size_t i = 1; i < w.size(); ++i) {
      const auto [k, v] = kv(w[i]);
      if (k == "from") f.from = node_of(v);
      else if (k == "to") f.to = node_of(v);
      else if (k == "type") f.type = v;
      else lines_.push_back("error: bad filter " + w[i]);
    }
    return f;
  }

  /// Delivers the matching datagrams now in flight; returns how many.
  std::size_t deliver(const Filter& f, bool print) {
    std::deque<Flight> now;
    std::deque<Flight> keep;
    for (auto& x : flight_) (f.matches(x) ? now : keep).push_back(std::move(x));
    flight_ = std::move(keep);
    for (const Flight& x : now) {
      if (!linked(x.from, x.to)) {
        if (print && !quiet_) lines_.push_back("> " + name(x.to) + " <- " + symbolic(x.bytes) + ": link cut, lost");
        continue;
      }
      open_block(x.to, "> " + name(x.to) + " <- " + symbolic(x.bytes));
      receive(x);
      settle(x.to);
      if (!print || quiet_) blocks_.clear();
      flush_blocks();
    }
    return now.size();
  }

  void receive(const Flight& x) {
    const Peer from = peer(x.from);
    if (x.to == 0) {
      if (!pc_) {
        block(0).push_back("  lost: the pc is down");
        return;
      }
      if (!pc_->handle_datagram(x.bytes, from, now_).taken()) block(0).push_back("  ignored");
      return;
    }
    Robot& r = *robots_[x.to - 1]->node;
    const std::size_t at = block(x.to).size();
    const NodeHandled h = r.handle_datagram(x.bytes, from, now_);
    const Ignored why = h.why();
    if (why == Ignored::undecodable || why == Ignored::off) {
      block(x.to).push_back("  ignored: " + std::string(to_string(why)));
    } else if (!h.agent.taken()) {
      // The agent core's Ignore line is the first this datagram printed (after the master core's).
      auto& b = block(x.to);
      for (std::size_t k = at; k < b.size(); ++k)
        if (b[k] == "  Ignore") {
          b[k] += ": " + std::string(to_string(h.agent.why));
          break;
        }
    }
  }

  void drop(const Filter& f) {
    std::deque<Flight> keep;
    std::size_t n = 0;
    for (auto& x : flight_) {
      if (f.matches(x)) ++n;
      else keep.push_back(std::move(x));
    }
    flight_ = std::move(keep);
    lines_.push_back("dropped " + std::to_string(n));
  }

  void dup(const Filter& f) {
    const std::size_t n = flight_.size();
    for (std::size_t k = 0; k < n; ++k)
      if (f.matches(flight_[k])) {
        lines_.push_back("copied " + name(flight_[k].from) + " -> " + name(flight_[k].to) + ": " + symbolic(flight_[k].bytes));
        flight_.push_back(flight_[k]);
      }
  }

  void stabilize(bool print) {
    for (int round = 0; !flight_.empty(); ++round) {
      if (round == 1000) {
        lines_.push_back("error: not stable after 1000 rounds");
        flight_.clear();
        return;
      }
      deliver(Filter{}, print);
    }
  }

  void cut(std::size_t a, std::size_t b) { down_.insert({std::min(a, b), std::max(a, b)}); }
  void partition(const std::vector<std::string>& w) {
    std::set<std::size_t> side;
    for (std::size_t i = 1; i < w.size(); ++i) side.insert(node_of(w[i]));
    for (std::size_t a = 0; a <= robots_.size(); ++a)
      for (std::size_t b = 0; b <= robots_.size(); ++b)
        if (side.count(a) != 0 && side.count(b) == 0) cut(a, b);
  }
  bool linked(std::size_t a, std::size_t b) const { return down_.count({std::min(a, b), std::max(a, b)}) == 0; }

  void command(const std::vector<std::string>& w, const std::string& line) {
    std::size_t at = 0, k = 1;
    if (w.size() > 1 && w[1].rfind("at=", 0) == 0) {
      at = node_of(w[1].substr(3));
      k = 2;
    }
    if (w.size() < k + 2) {
      lines_.push_back("error: bad command: " + line);
      return;
    }
    std::uint16_t id = 0;
    if (w[k] != "all") id = w[k][0] == 'a' ? robots_[node_of(w[k]) - 1]->node->agent().id()
                                           : static_cast<std::uint16_t>(std::stoul(w[k]));
    MsgType t;
    if (!command_type(w[k + 1], t)) {
      lines_.push_back("error: bad command " + w[k + 1]);
      return;
    }
    Command c = Command::simple(t);
    if (t == MsgType::BEHAVIOUR && w.size() >= k + 3) c = Command::assign(w[k + 2], {w.begin() + static_cast<long>(k) + 3, w.end()});
    open_block(at, "> " + name(at) + " operator: " + line.substr(line.find(' ') + 1));
    if (at == 0) {
      if (pc_) pc_->command(id, c, now_);
    } else if (!robots_[at - 1]->node->command(id, c, now_)) {
      block(at).push_back("  refused: no Master core runs here");
    }
    settle(at);
  }

  void event(const std::vector<std::string>& w) {
    const std::size_t i = node_of(w[1]);
    if (i == 0 || i > robots_.size()) {
      lines_.push_back("error: no robot " + w[1]);
      return;
    }
    Robot& r = *robots_[i - 1]->node;
    open_block(i, "> " + name(i) + " event " + w[2]);
    const std::string& e = w[2];
    bool ok = false;
    if (e == "action_ok") ok = r.action_ok(now_);
    else if (e == "action_failed") ok = r.action_failed(words_from(w, 3), now_);
    else if (e == "obstacle") ok = r.action_interrupted(Warning::OBSTACLE_DETECTED, now_);
    else if (e == "battery_low") ok = r.battery_low(now_);
    else if (e == "unplug" && w.size() == 5) ok = r.device_unplugged(static_cast<std::uint32_t>(std::stoul(w[3])), w[4], now_);
    else if (e == "plug" && w.size() == 5) ok = r.device_plugged(static_cast<std::uint32_t>(std::stoul(w[3])), w[4], now_);
    else lines_.push_back("error: bad event " + e);
    if (!ok) block(i).push_back("  not enabled");
    settle(i);
  }

  void crash_pc() {
    if (!pc_) return;
    pc_cfg_.next_id = pc_->next_id();
    pc_cfg_.next_msgid = pc_->next_msgid();
    pc_cfg_.epoch = pc_->epoch();
    pc_cfg_.members = pc_->members();  // the state file: the membership of its epoch, not want()
    pc_cfg_.members_epoch = pc_->members_epoch();
    pc_cfg_.candidate = true;
    pc_.reset();
    lines_.push_back("> pc crashed");
  }
  void restart_pc() {
    pc_ = std::make_unique<Pc>(pc_cfg_, now_, &pc_sink_);
    lines_.push_back("> pc restarted (candidate, epoch " + std::to_string(pc_cfg_.epoch) + ")");
  }

  void show() {
    if (pc_) {
      std::string l = "pc: " + std::string(to_string(pc_->role())) + " epoch=" + std::to_string(pc_->epoch()) + " reg=";
      for (const auto& kv2 : pc_->registry())
        l += std::to_string(kv2.first) + (kv2.second.synced ? "" : "?") +
             (kv2.second.via ? "via" + std::to_string(kv2.second.via) : "") + ",";
      lines_.push_back(l);
    }
    for (std::size_t i = 1; i <= robots_.size(); ++i) {
      const Robot& r = *robots_[i - 1]->node;
      const auto& a = r.agent();
      std::string l = name(i) + ": id=" + std::to_string(a.id()) + " " + std::string(to_string(a.state()));
      if (a.election().role != ElectionRole::none) l += "/" + std::string(to_string(a.election().role));
      l += " epoch=" + std::to_string(a.election().epoch) + " voted=" + std::to_string(a.durable().voted_for) +
           " leader=" + std::to_string(a.election().leader) + " via=" + std::to_string(a.election().via) + " relays=[";
      for (std::size_t k = 0; k < a.election().relays.size(); ++k) l += (k ? "," : "") + std::to_string(a.election().relays.id(k));
      l += "]";
      if (const auto* m = r.master()) l += " master_core=" + std::string(to_string(m->role())) + "@" + std::to_string(m->epoch());
      lines_.push_back(l);
    }
  }

  // ------------------------------------------------------------------ plumbing

  /// What node @p i queued: datagrams (into the network) and events, as lines.
  std::vector<std::string> drain(std::size_t i) {
    std::vector<std::string> out;
    if (i == 0) {
      MasterTransmit t;
      while (pc_ && pc_->poll_transmit(t)) out.push_back(send(0, t.dest, t.peer, t.bytes));
      OperatorEvent e;
      while (pc_ && pc_->poll_event(e)) out.push_back(op_line(e));
      return out;
    }
    Robot& r = *robots_[i - 1]->node;
    NodeTransmit t;
    while (r.poll_transmit(t)) out.push_back(send(i, t.dest, t.peer, std::string(t.bytes)));
    OperatorEvent oe;
    while (r.poll_operator_event(oe)) out.push_back(op_line(oe));
    NodeEvent e;
    while (r.poll_event(e)) {
      if (e.kind == NodeEvent::Kind::state || e.kind == NodeEvent::Kind::led || e.kind == NodeEvent::Kind::control)
        out.push_back(event_line(r, e));
      else
        pending_[i].push_back(event_line(r, e));  // the node's own: after the actions of the input
    }
    return out;
  }

  std::string send(std::size_t from, Dest dest, Peer to, const std::string& bytes) {
    if (dest == Dest::broadcast) {
      for (std::size_t k = 0; k <= robots_.size(); ++k)
        if (k != from) flight_.push_back(Flight{from, k, bytes});
      return "send all " + symbolic(bytes);
    }
    const std::size_t k = to == kPcPeer ? 0 : static_cast<std::size_t>(to) - 1;
    if (to == 0 || k > robots_.size()) return "send nowhere (no address) " + symbolic(bytes);
    flight_.push_back(Flight{from, k, bytes});
    return "send " + name(k) + " " + symbolic(bytes);
  }

  static std::string event_line(const Robot& r, const NodeEvent& e) {
    switch (e.kind) {
      case NodeEvent::Kind::state: return "state " + std::string(to_string(e.state));
      case NodeEvent::Kind::led: return "led " + std::string(to_string(e.led));
      case NodeEvent::Kind::control: {
        std::string l = "control " + std::string(to_string(e.control));
        if (e.control == ControlKind::start || e.control == ControlKind::restart) l += " " + std::string(r.agent().behaviour().name);
        return l;
      }
      case NodeEvent::Kind::durable:
        return "durable epoch=" + std::to_string(e.durable.epoch) + " votedFor=" + std::to_string(e.durable.voted_for) + " mepoch=" + std::to_string(e.durable.mepoch) + " floor=" + std::to_string(e.durable.floor);
      case NodeEvent::Kind::role: return "role " + std::string(to_string(e.role)) + " epoch=" + std::to_string(e.epoch);
      case NodeEvent::Kind::leader:
        return "leader " + std::to_string(e.leader) + " epoch=" + std::to_string(e.epoch) + " via=" + std::to_string(e.via);
      case NodeEvent::Kind::relays: {
        std::string l = "relays [";
        for (std::size_t k = 0; k < r.agent().election().relays.size(); ++k) l += (k ? "," : "") + std::to_string(r.agent().election().relays.id(k));
        return l + "]";
      }
      case NodeEvent::Kind::master_started: return "master_started epoch=" + std::to_string(e.epoch);
      case NodeEvent::Kind::master_stopped:
        return "master_stopped epoch=" + std::to_string(e.epoch) + (e.handed_over ? " handed_over" : "");
    }
    return {};
  }

  /// After an input of node @p i: its remaining outputs, then its own events.
  void settle(std::size_t i) {
    for (auto& l : drain(i)) block(i).push_back("  " + l);
    for (auto& l : pending_[i]) block(i).push_back("  " + l);
    pending_[i].clear();
  }

  std::vector<std::string>& block(std::size_t i) { return blocks_[i].second; }
  void open_block(std::size_t i, std::string head) { blocks_[i].first = std::move(head); }
  /// The blocks written, each under its head line, in node order; empty ones vanish.
  void flush_blocks() {
    for (auto& b : blocks_) {
      if (b.second.second.empty()) continue;
      if (!quiet_) {
        lines_.push_back(b.second.first.empty() ? "> " + name(b.first) : b.second.first);
        for (auto& l : b.second.second) lines_.push_back(std::move(l));
      }
    }
    blocks_.clear();
  }

  std::string name(std::size_t i) const { return i == 0 ? "pc" : "a" + std::to_string(i); }
  std::size_t node_of(const std::string& n) const {
    if (n == "pc") return 0;
    if (n.size() > 1 && n[0] == 'a') return std::stoul(n.substr(1));
    return kAny;
  }
  static Peer peer(std::size_t i) { return i == 0 ? kPcPeer : static_cast<Peer>(i + 1); }
  static std::pair<std::string, std::string> kv(const std::string& w) {
    const auto eq = w.find('=');
    return {w.substr(0, eq), eq == std::string::npos ? "" : w.substr(eq + 1)};
  }
  static bool set_timer(Timers& t, const std::string& k, const std::string& v) {
    for (const TimerSpec& s : kTimerTable)
      if (s.name == k) {
        t.set(s.timer, std::stoull(v));
        return true;
      }
    return false;
  }

  static constexpr BehaviourSpec kBehaviours[] = {{"explore", 1u}};

  Millis now_ = 0;
  std::unique_ptr<Pc> pc_;
  MasterConfig pc_cfg_;
  FleetMasterSink pc_sink_;
  std::vector<std::unique_ptr<Member>> robots_;
  std::deque<Flight> flight_;
  std::set<std::pair<std::size_t, std::size_t>> down_;
  std::map<std::size_t, std::pair<std::string, std::vector<std::string>>> blocks_;
  std::map<std::size_t, std::vector<std::string>> pending_;
  std::vector<std::string> lines_;
  bool quiet_ = false;
};

template <typename A>
void FleetAgentSink::record(const AgentTraceRecord& r, const A&) {
  driver->on_agent(node, r);
}
inline void FleetMasterSink::record(const MasterTraceRecord& r) { driver->on_master(node, r); }

}  // namespace ev3test
