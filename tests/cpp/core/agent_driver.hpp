// Drives one Agent from transcript commands (tests/cpp/testdata/agent_*.txt) and prints what it
// did. Shared by the transcript test and the trace test.
//
// Inputs:
//   agent [temp=N] [model=M] [behaviours=name:devbits,...] [devices=bits] [sync=ms] [heartbeat=ms]
//         [loss=ms] [paused=ms] [at=ms] [window=N] [first_msgid=N]
//         [election=1 score=N epoch=N voted=N relay_retry=ms
//         backoff=ms backoff_step=ms candidate=ms vouch=ms backoff_jitter=ms seed=N]
//                                              (re)create the agent at time `at` (default 0); timers
//                                              not given are fixed_timers.hpp's
//   advance MS                                   time moves MS milliseconds
//   recv DATAGRAM [from=PEER]                    a datagram arrives (symbolic: 1->7 START #3, or
//                                                wire bytes: 1:7:3:8); PEER defaults to 1
//   event obstacle|proximity|action_ok|action_failed [REASON...]|battery_low|unplug BITS PORT|plug BITS PORT
//   event robot NAME PORT                        a robot event (RobotEvent: OBSTACLE_DETECTED, ...)
//   event sensor PORT MODE VALUE...
//   check NAME REASON...                         from now on the robot's check on receipt refuses
//                                                BEHAVIOUR NAME with REASON (`check NAME ok`: accepts
//                                                it again); without one every behaviour passes
//   show                                         the election variables
//   trace                                        print the NDJSON trace lines of this case
// Outputs: each spec action the agent took, by name (`Ignore: REASON` when a datagram was not
// taken, `ApplyCommand: RecvStart` with the inner handler; a run of Ticks only when it sent
// something), followed, indented, by what that action did: `send master|broadcast|peer=P DATAGRAM`
// (symbolic, tests/cpp/core/symbolic.hpp), `state S`, `led L`, `control K [name args...]`. A
// datagram no action saw: `ignored: REASON`. Last: `deadline T` (or `deadline none`).
#pragma once

#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "fixed_timers.hpp"
#include "ev3proto/agent.hpp"
#include "ev3proto/trace.hpp"
#include "symbolic.hpp"

namespace ev3test {

using namespace ev3proto;

class AgentDriver;

/// Trace sink: each action's name, followed by what it sent and emitted (the driver drains the
/// agent's queues at every record), and the NDJSON lines.
struct LogTrace {
  static constexpr bool enabled = true;
  AgentDriver* driver = nullptr;
  std::vector<std::string> json;
  template <typename A>
  void record(const AgentTraceRecord& r, const A& a);
};

using TracedAgent = Agent<LogTrace>;

/// The transcript line of one transmit.
inline std::string send_line(Dest dest, Peer peer, std::string_view bytes) {
  return "  send " + std::string(to_string(dest)) + (dest == Dest::peer ? "=" + std::to_string(peer) : std::string()) +
         " " + symbolic(bytes);
}

/// The wire bytes of a transcript's datagram (symbolic or raw); "" and @p error when malformed.
inline std::string datagram_arg(const std::string& text, std::string& error) {
  if (!is_symbolic(text)) return text;
  std::string bytes;
  if (!parse_symbolic(text, bytes, error)) return {};
  return bytes;
}

inline std::vector<std::string> words(const std::string& line) {
  std::istringstream in(line);
  std::vector<std::string> w;
  for (std::string s; in >> s;) w.push_back(s);
  return w;
}

/// One agent and its surroundings (capabilities storage, time).
class AgentDriver {
 public:
  /// Runs one case's input lines; returns the output lines.
  std::vector<std::string> run(const std::vector<std::string>& input) {
    lines_.clear();
    trace_.json.clear();
    trace_.driver = this;
    bool show_trace = false;
    for (const std::string& line : input) step(line, show_trace);
    if (show_trace)
      for (const auto& j : trace_.json) lines_.push_back("trace " + j);
    const Millis d = agent_ ? agent_->next_deadline() : TracedAgent::kNever;
    lines_.push_back(d == TracedAgent::kNever ? "deadline none" : "deadline " + std::to_string(d));
    return lines_;
  }

  TracedAgent* agent() { return agent_.get(); }

  /// Called by the trace sink after each action: its name, then what it queued.
  void on_record(const AgentTraceRecord& r) {
    std::vector<std::string> out = drain();
    if (r.action == Action::Tick && out.empty()) return;
    std::string name(to_string(r.action));
    if (r.action == Action::ApplyCommand) name += ": " + std::string(to_string(r.cmd));
    lines_.push_back(name);
    for (auto& l : out) lines_.push_back(std::move(l));
  }

 private:
  void step(const std::string& line, bool& show_trace) {
    const auto w = words(line);
    if (w.empty()) return;
    if (w[0] == "agent") {
      create(w);
    } else if (!agent_) {
      lines_.push_back("error: no agent (start the file with `agent`)");
    } else if (w[0] == "advance" && w.size() == 2) {
      now_ += std::stoull(w[1]);
      agent_->advance(now_);
    } else if (w[0] == "recv" && w.size() >= 2) {
      recv(line);
    } else if (w[0] == "event" && w.size() >= 2) {
      event(w);
    } else if (w[0] == "trace") {
      show_trace = true;
    } else if (w[0] == "check" && w.size() >= 3) {
      const std::string reason = line.substr(line.find(w[1], line.find("check") + 5) + w[1].size() + 1);
      if (reason == "ok")
        refusals_.erase(w[1]);
      else
        refusals_[w[1]] = reason;
    } else if (w[0] == "show") {
      lines_.push_back(show());
    } else {
      lines_.push_back("error: bad input: " + line);
    }
  }

  /// recv DATAGRAM [from=PEER]: the datagram's action line gets the reason when it was not taken.
  void recv(const std::string& line) {
    std::string text = line.substr(line.find(' ') + 1);
    Peer from = 1;
    const auto f = text.rfind(" from=");
    if (f != std::string::npos) {
      from = static_cast<Peer>(std::stoul(text.substr(f + 6)));
      text = text.substr(0, f);
    }
    std::string error;
    const std::string bytes = datagram_arg(text, error);
    if (!error.empty()) {
      lines_.push_back("error: " + error);
      return;
    }
    agent_->advance(now_);  // the records of time moving come first
    const std::size_t at = lines_.size();
    const Handled h = agent_->handle_datagram(bytes, from, now_);
    if (h.why == Ignored::undecodable) {
      lines_.push_back("ignored: undecodable (" + std::string(to_string(h.decode.reason)) + ", field " +
                       std::to_string(h.decode.field) + ")");
    } else if (h.why == Ignored::off) {
      lines_.push_back("ignored: off");
    } else if (!h.taken() && at < lines_.size()) {
      lines_[at] += ": " + std::string(to_string(h.why));
    }
    for (auto& l : drain()) lines_.push_back(std::move(l));  // nothing, unless a record was missed
  }

  void create(const std::vector<std::string>& w) {
    AgentConfig c;
    c.timers = ev3test::fixed_timers();
    c.temp_id = 50001;
    names_.clear();
    behs_.clear();
    std::string model = "A";
    std::string behaviours = "explore:1,wander:0";
    std::uint32_t devices = 1;
    Millis at = 0;
    for (std::size_t i = 1; i < w.size(); ++i) {
      const auto eq = w[i].find('=');
      const std::string k = w[i].substr(0, eq), v = eq == std::string::npos ? "" : w[i].substr(eq + 1);
      if (k == "temp") c.temp_id = static_cast<std::uint16_t>(std::stoul(v));
      else if (k == "window") c.window = static_cast<std::size_t>(std::stoul(v));
      else if (k == "first_msgid") c.first_msgid = static_cast<std::uint32_t>(std::stoul(v));
      else if (k == "model") model = v;
      else if (k == "behaviours") behaviours = v;
      else if (k == "devices") devices = static_cast<std::uint32_t>(std::stoul(v));
      else if (k == "at") at = std::stoull(v);
      else if (k == "sync") c.timers.set(Timer::sync, std::stoull(v));
      else if (k == "heartbeat") c.timers.set(Timer::heartbeat, std::stoull(v));
      else if (k == "loss") c.timers.set(Timer::loss, std::stoull(v));
      else if (k == "paused") c.timers.set(Timer::paused, std::stoull(v));
      else if (k == "relay_retry") c.timers.set(Timer::relay_retry, std::stoull(v));
      else if (k == "backoff") c.timers.set(Timer::backoff, std::stoull(v));
      else if (k == "backoff_step") c.timers.set(Timer::backoff_step, std::stoull(v));
      else if (k == "candidate") c.timers.set(Timer::candidate, std::stoull(v));
      else if (k == "vouch") c.timers.set(Timer::vouch, std::stoull(v));
      else if (k == "backoff_jitter") c.timers.set(Timer::backoff_jitter, std::stoull(v));
      else if (k == "seed") c.election.seed = static_cast<std::uint32_t>(std::stoul(v));
      else if (k == "election") c.election.enabled = v == "1";
      else if (k == "score") c.election.score = static_cast<std::uint32_t>(std::stoul(v));
      else if (k == "epoch") c.election.durable.epoch = static_cast<std::uint32_t>(std::stoul(v));
      else if (k == "voted") c.election.durable.voted_for = static_cast<std::uint16_t>(std::stoul(v));
      else if (k == "mepoch") c.election.durable.mepoch = static_cast<std::uint32_t>(std::stoul(v));
      else if (k == "floor") c.election.durable.floor = static_cast<std::uint32_t>(std::stoul(v));
      else if (k == "members") {  // the membership restored from the SD card: members=7,8,9
        std::istringstream ids(v);
        for (std::string id; std::getline(ids, id, ',') && c.election.durable.member_count < kMaxMembership;)
          c.election.durable.members[c.election.durable.member_count++] = static_cast<std::uint16_t>(std::stoul(id));
      }
      else lines_.push_back("error: bad agent option " + w[i]);
    }
    model_ = model;
    std::istringstream in(behaviours);
    for (std::string item; std::getline(in, item, ',');) {
      const auto colon = item.find(':');
      names_.push_back(item.substr(0, colon));
      behs_.push_back(BehaviourSpec{{}, colon == std::string::npos ? 0u : static_cast<std::uint32_t>(std::stoul(item.substr(colon + 1)))});
    }
    for (std::size_t i = 0; i < behs_.size(); ++i) behs_[i].name = names_[i];
    c.caps = Capabilities{model_, behs_.data(), behs_.size(), devices};
    refusals_.clear();
    c.check.ctx = &refusals_;
    c.check.fn = [](void* ctx, std::string_view name, const std::string_view*, std::size_t, CheckReason& why) noexcept {
      const auto& table = *static_cast<const std::map<std::string, std::string, std::less<>>*>(ctx);
      const auto it = table.find(name);
      if (it == table.end()) return true;
      why.set(it->second);
      return false;
    };
    now_ = at;
    agent_ = std::make_unique<TracedAgent>(c, now_, &trace_);
    for (auto& l : drain()) lines_.push_back(std::move(l));
  }

  void event(const std::vector<std::string>& w) {
    const std::string& e = w[1];
    if (e == "obstacle") agent_->action_interrupted(Warning::OBSTACLE_DETECTED, now_);
    else if (e == "proximity") agent_->action_interrupted(Warning::PROXIMITY_ALERT, now_);
    else if (e == "action_ok") agent_->action_ok(now_);
    else if (e == "action_failed") agent_->action_failed(words_from(w, 2), now_);
    else if (e == "battery_low") agent_->battery_low(now_);
    else if (e == "unplug" && w.size() == 4) agent_->device_unplugged(static_cast<std::uint32_t>(std::stoul(w[2])), w[3], now_);
    else if (e == "plug" && w.size() == 4) agent_->device_plugged(static_cast<std::uint32_t>(std::stoul(w[2])), w[3], now_);
    else if (e == "robot" && w.size() == 4) {
      RobotEventKind k{};
      if (!parse_robot_event(w[2], k)) lines_.push_back("error: bad robot event " + w[2]);
      else if (!agent_->robot_event(k, w[3], now_)) lines_.push_back("robot event refused");
    }
    else if (e == "sensor" && w.size() >= 5) {
      std::vector<std::string_view> v(w.begin() + 4, w.end());
      if (!agent_->sensor_report(w[2], w[3], v.data(), v.size(), now_)) lines_.push_back("sensor refused");
    } else {
      lines_.push_back("error: bad event " + e);
    }
  }

  /// Election variables: life (role), epoch, votedFor, leader, following, via, relays, votes, members.
  std::string show() const {
    const TracedAgent& a = *agent_;
    auto list = [](std::size_t n, auto get) {
      std::string l = "[";
      for (std::size_t i = 0; i < n; ++i) l += (i ? "," : "") + std::to_string(get(i));
      return l + "]";
    };
    const auto& el = a.election();
    return "show state=" + std::string(to_string(a.state())) + " role=" + std::string(to_string(el.role)) +
           " epoch=" + std::to_string(el.epoch) + " votedFor=" + std::to_string(a.durable().voted_for) +
           " leader=" + std::to_string(el.leader) + " following=" + std::to_string(el.following) +
           " via=" + std::to_string(el.via) +
           " relays=" + list(el.relays.size(), [&](std::size_t i) { return el.relays.id(i); }) +
           " offered=" + list(el.offered.size(), [&](std::size_t i) { return el.offered.id(i); }) +
           " votes=" + list(el.votes.size(), [&](std::size_t i) { return el.votes[i]; }) +
           " prevotes=" + list(el.prevotes.size(), [&](std::size_t i) { return el.prevotes[i]; }) +
           " members=" + list(el.members.size(), [&](std::size_t i) { return el.members[i]; }) +
           " mepoch=" + std::to_string(el.mepoch) + " floor=" + std::to_string(el.floor) +
           " master_epoch=" + std::to_string(el.master_epoch);
  }

  /// What the agent queued since the last drain: datagrams, then state, LED and control events.
  std::vector<std::string> drain() {
    std::vector<std::string> lines;
    Transmit t;
    while (agent_ && agent_->poll_transmit(t)) lines.push_back(send_line(t.dest, t.peer, t.bytes));
    AgentEvent e;
    while (agent_ && agent_->poll_event(e)) {
      switch (e.kind) {
        case AgentEvent::Kind::state: lines.push_back("  state " + std::string(to_string(e.state))); break;
        case AgentEvent::Kind::led: lines.push_back("  led " + std::string(to_string(e.led))); break;
        case AgentEvent::Kind::control: {
          std::string l = "  control " + std::string(to_string(e.control));
          if (e.control == ControlKind::start || e.control == ControlKind::restart) {
            const BehaviourView b = agent_->behaviour();
            l += " " + std::string(b.name);
            for (std::size_t i = 0; i < b.arg_count; ++i) l += " " + std::string(b.arg(i));
          }
          lines.push_back(l);
          break;
        }
      }
    }
    return lines;
  }

  LogTrace trace_;
  std::unique_ptr<TracedAgent> agent_;
  Millis now_ = 0;
  std::string model_;
  std::vector<std::string> names_;
  std::vector<BehaviourSpec> behs_;
  std::map<std::string, std::string, std::less<>> refusals_;  // the robot's check: behaviour -> reason
  std::vector<std::string> lines_;
};

template <typename A>
void LogTrace::record(const AgentTraceRecord& r, const A& a) {
  json.push_back(to_ndjson(r, a));
  if (driver != nullptr) driver->on_record(r);
}

}  // namespace ev3test
