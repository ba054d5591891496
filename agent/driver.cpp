// ev3-agent --driver: the agent core on a virtual clock, no sockets; NDJSON on stdin/stdout, one
// output line per input line (docs/driver.md). Logs go to stderr. The conformance runner
// (conformance/, `ev3-conformance replay`) drives it with the spec's behaviours.
#include "driver.hpp"

#include <cstdio>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <ev3proto/agent.hpp>
#include <ev3proto/durable.hpp>
#include <ev3proto/json.hpp>
#include <ev3proto/robot/behaviours.hpp>
#include <ev3proto/trace.hpp>
#include <ev3proto/wire.hpp>

#include "ev3prog/driver_json.hpp"
#include "ev3prog/program.hpp"
#include "agent_sink.hpp"

namespace ev3agent {
namespace {

using ev3prog::Json;
using ev3proto::json_string;
using ev3proto::Millis;

class Driver {
 public:
  explicit Driver(std::FILE* trace) : trace_(trace) {
    sink_.actions = &actions_;
    if (trace_ != nullptr)
      sink_.ndjson = [this](const std::string& line) {
        std::fwrite(line.data(), 1, line.size(), trace_);
        std::fputc('\n', trace_);
      };
  }

  int run() {
    return ev3prog::run_driver_lines(trace_, seq_, [this](const std::string& line) { return handle(line); });
  }

  // Below: what ev3prog::dispatch_input() asks of a driver (configure() among it), then output().
  bool configure(const Json& in, std::string& err) {
    ev3proto::AgentConfig c;
    const Json& t = in["timers"];
    for (const ev3proto::TimerSpec& r : ev3proto::kTimerTable) {
      const std::string name(r.name);
      if (t.has(name)) c.timers.set(r.timer, static_cast<Millis>(t[name].num(1)));
    }
    // Relay and election (Election.tla): {"enabled", "score", "epoch", "voted_for", and the membership
    // its state keeps: "members" [ids], "members_epoch", "floor"}, checked as ev3-agent checks its
    // state file (ev3proto::parse_durable).
    const Json& el = in["election"];
    c.election.enabled = el["enabled"].boolean(false);
    if (el.has("score")) c.election.score = static_cast<std::uint32_t>(el["score"].num(0));
    if (el.has("seed")) c.election.seed = static_cast<std::uint32_t>(el["seed"].num(0));
    if (!restore_durable(el, c.election.durable, err)) return false;
    if (!c.timers.valid()) {
      err = "timers: paused must be greater than loss";
      return false;
    }
    model_ = in["model"].str("A");
    beh_names_.clear();
    behs_.clear();
    refusals_.clear();
    if (in["behaviours"].kind == Json::Kind::array) {
      for (const Json& b : in["behaviours"].a) {
        beh_names_.push_back(b["name"].str());
        if (b.has("refuse")) refusals_[b["name"].str()] = b["refuse"].str();
      }
      std::size_t i = 0;
      for (const Json& b : in["behaviours"].a)
        behs_.push_back({beh_names_[i++], static_cast<std::uint32_t>(b["devices"].num(0))});
    } else {
      beh_names_.push_back("wait");
      behs_.push_back({beh_names_[0], 0});
    }
    c.caps = {model_, behs_.data(), behs_.size(), static_cast<std::uint32_t>(in["devices"].num(1))};
    c.check = check();
    if (in.has("temp_id")) draw_temp_ = in["temp_id"].num();
    if (in.has("first_msgid")) draw_msgid_ = in["first_msgid"].num();
    c.temp_id = static_cast<std::uint16_t>(draw_temp_);
    c.first_msgid = static_cast<std::uint32_t>(draw_msgid_);
    const long long w = in["window"].num(static_cast<long long>(AgentCore::WindowType::capacity()));
    if (w < 1 || w > static_cast<long long>(AgentCore::WindowType::capacity())) {
      err = "window must be 1.." + std::to_string(AgentCore::WindowType::capacity());
      return false;
    }
    c.window = static_cast<std::size_t>(w);
    const Millis now = static_cast<Millis>(in["now"].num(0));
    core_.emplace(c, now, &sink_);
    snaps_.clear();
    std::fprintf(stderr, "ev3-agent --driver: configured (model %s, temporary id %lld, window %lld, now %llu)\n",
                 model_.c_str(), draw_temp_, w, static_cast<unsigned long long>(now));
    return true;
  }

  std::string handle(const std::string& line) { return ev3prog::dispatch_input(*this, line); }

  std::string error(const std::string& msg) { return ev3prog::driver_error("ev3-agent --driver", seq_, msg); }
  void clear_actions() { actions_.clear(); }
  bool has_core() const { return core_.has_value(); }
  Millis core_now() const { return core_->now(); }
  void core_advance(Millis to) { core_->advance(to); }
  void core_recv(const std::string& bytes, const Json& in, Millis now) {
    core_->handle_datagram(bytes, static_cast<ev3proto::Peer>(in["from"].num(1)), now);
  }
  /// "random" (the ids and msgids the agent will draw) and "facts" need no core.
  bool early(const std::string& type, const Json& in, std::string& reply) {
    if (type == "facts") {
      reply = ev3prog::output_start(seq_, true) + ",\"facts\":" + facts_json() + "}";
      return true;
    }
    if (type != "random") return false;
    if (in.has("temp_id")) draw_temp_ = in["temp_id"].num();
    if (in.has("first_msgid")) draw_msgid_ = in["first_msgid"].num();
    reply = output(true);
    return true;
  }
  std::string own(const std::string& type, const Json& in, Millis now) {
    std::string err;
    if (type == "event") {
      const bool ok = event(in["event"].str(), in, now, err);
      if (!err.empty()) return error(err);
      return output(ok);
    }
    if (type == "save") {
      snaps_.insert_or_assign(in["slot"].num(), *core_);
      return output(true);
    }
    if (type == "restore") {
      const auto it = snaps_.find(in["slot"].num());
      if (it == snaps_.end()) return error("no snapshot in that slot");
      *core_ = it->second;
      actions_.clear();
      drain_sent();
      std::string c;
      drain_events(c);
      return output(true);
    }
    return error("unknown input type '" + type + "'");
  }
  std::string output(bool taken) {
    if (!core_) return ev3prog::output_start(seq_, taken) + "}";
    std::string s = ev3prog::output_start(seq_, taken, core_->now(), actions_) + ",\"sent\":" + drain_sent();
    std::string controls;
    s += ",\"events\":" + drain_events(controls);
    s += ",\"controls\":" + controls;
    const Millis d = core_->next_deadline();
    s += ",\"deadline\":" + (d == AgentCore::kNever ? std::string("null") : std::to_string(d));
    s += ",\"vars\":" + vars_json(core_->vars(), *core_);
    if (core_->vars().election) s += ",\"election\":" + election_json(*core_);
    return s + "}";
  }

  /// What ev3-agent runs with, for a checker that has no other way to know it (docs/driver.md
  /// "facts"): model A and its behaviours, each with the devices it needs (robot::kModelABehaviours,
  /// the table the program gives its agent core).
  static std::string facts_json() {
    std::string s = "{\"model\":\"A\",\"behaviours\":[";
    for (const auto& b : ev3proto::robot::kModelABehaviours) {
      s += s.back() == '[' ? "{\"name\":" : ",{\"name\":";
      json_string(s, b.name);
      s += ",\"devices\":" + std::to_string(b.devices) + "}";
    }
    return s + "]}";
  }

  /// The agent's Election.tla variables after the input (docs/driver.md "Output"): life (the
  /// state, or CANDIDATE / MASTER by the election role), epoch, votedFor, votes, leader, following,
  /// via, relays, offered, prevotes, members, mepoch, floor (0 = NoNode / none).
  static std::string election_json(const AgentCore& c) {
    auto ids = [](std::size_t n, auto at) {
      std::string s = "[";
      for (std::size_t i = 0; i < n; ++i) s += (i ? "," : "") + std::to_string(at(i));
      return s + "]";
    };
    const auto& el = c.election();
    const ev3proto::ElectionRole r = el.role;
    const std::string life = r == ev3proto::ElectionRole::master      ? "MASTER"
                             : r == ev3proto::ElectionRole::candidate ? "CANDIDATE"
                                                              : std::string(to_string(c.vars().state));
    return "{\"life\":\"" + life + "\",\"epoch\":" + std::to_string(el.epoch) +
           ",\"votedFor\":" + std::to_string(c.durable().voted_for) +
           ",\"votes\":" + ids(el.votes.size(), [&](std::size_t i) { return el.votes[i]; }) +
           ",\"leader\":" + std::to_string(el.leader) + ",\"following\":" + std::to_string(el.following) +
           ",\"via\":" + std::to_string(el.via) +
           ",\"relays\":" + ids(el.relays.size(), [&](std::size_t i) { return el.relays.id(i); }) +
           ",\"offered\":" + ids(el.offered.size(), [&](std::size_t i) { return el.offered.id(i); }) +
           ",\"prevotes\":" + ids(el.prevotes.size(), [&](std::size_t i) { return el.prevotes[i]; }) +
           ",\"members\":" + ids(el.members.size(), [&](std::size_t i) { return el.members[i]; }) +
           ",\"mepoch\":" + std::to_string(el.mepoch) + ",\"floor\":" + std::to_string(el.floor) +
           ",\"master_epoch\":" + std::to_string(el.master_epoch) + "}";
  }

 private:
  /// The durable state of config's "election" object (epoch, voted_for, members, members_epoch,
  /// floor) into @p d, read and checked as ev3-agent reads its state file: the same keys as text,
  /// the library's rule (ev3proto/durable.hpp). False with the key named in @p err.
  static bool restore_durable(const Json& el, ev3proto::Durable& d, std::string& err) {
    auto number = [](const Json& v) { return v.kind == Json::Kind::number ? std::to_string(v.num()) : std::string("?"); };
    std::string text = "epoch=" + (el.has("epoch") ? number(el["epoch"]) : std::string("1")) +
                       "\nvoted_for=" + (el.has("voted_for") ? number(el["voted_for"]) : std::string("0")) + "\n";
    if (el.has("members")) {
      if (el["members"].kind != Json::Kind::array) {
        err = "election: members must be an array of agent ids";
        return false;
      }
      std::string ids;
      for (const Json& id : el["members"].a) ids += (ids.empty() ? "" : ",") + number(id);
      text += "members=" + ids + "\n";
    }
    for (const char* k : {"members_epoch", "floor"})
      if (el.has(k)) text += std::string(k) + "=" + number(el[k]) + "\n";
    ev3proto::DurableError why;
    if (!ev3proto::parse_durable(text, d, why)) {
      err = "election: " + std::string(why.view());
      return false;
    }
    return true;
  }

  /// A device or behaviour event for the core (docs/driver.md "event").
  bool event(const std::string& name, const Json& in, Millis now, std::string& err) {
    if (name == "action_ok") return core_->action_ok(now);
    if (name == "action_failed") return core_->action_failed(in["reason"].str("error"), now);
    if (name == "battery_low") return core_->battery_low(now);
    if (name == "action_interrupted") {
      const std::string w = in["warning"].str("OBSTACLE_DETECTED");
      if (w != "OBSTACLE_DETECTED" && w != "PROXIMITY_ALERT") {
        err = "unknown warning '" + w + "' (OBSTACLE_DETECTED or PROXIMITY_ALERT)";
        return false;
      }
      return core_->action_interrupted(
          w == "OBSTACLE_DETECTED" ? ev3proto::Warning::OBSTACLE_DETECTED : ev3proto::Warning::PROXIMITY_ALERT,
          now);
    }
    if (name == "sensor_report") {
      std::vector<std::string> vals;
      for (const Json& v : in["values"].a) vals.push_back(v.str());
      if (vals.empty()) vals.push_back("value");
      std::vector<std::string_view> views(vals.begin(), vals.end());
      return core_->sensor_report(in["port"].str("port"), in["mode"].str("mode"), views.data(), views.size(), now);
    }
    if (name == "device_unplugged" || name == "device_plugged" || name == "robot_event") {
      const std::string port = in["port"].str();
      if (!ev3proto::is_port_name(port)) {
        err = name + " needs a port (in1..in4, outA..outD), not '" + port + "'";
        return false;
      }
      if (name == "robot_event") {
        ev3proto::RobotEventKind k{};
        const std::string e = in["name"].str();
        if (!ev3proto::parse_robot_event(e, k)) {
          err = "unknown robot event '" + e + "' (OBSTACLE_DETECTED, PROXIMITY_ALERT, DEVICE_CONNECTED, DEVICE_DISCONNECTED)";
          return false;
        }
        return core_->robot_event(k, port, now);
      }
      const auto bits = static_cast<std::uint32_t>(in["devices"].num(1));
      return name == "device_unplugged" ? core_->device_unplugged(bits, port, now)
                                        : core_->device_plugged(bits, port, now);
    }
    err = "unknown event '" + name + "'";
    return false;
  }
  std::string drain_sent() {
    std::string s = "[";
    ev3proto::Transmit t;
    while (core_->poll_transmit(t)) {
      if (s.size() > 1) s += ',';
      s += "{\"to\":\"" + std::string(to_string(t.dest)) + "\"";
      if (t.dest == ev3proto::Dest::master) s += ",\"peer\":" + std::to_string(t.peer);
      s += ",\"text\":";
      json_string(s, t.bytes);
      s += ",\"hex\":\"" + ev3prog::hex(t.bytes) + "\"}";
    }
    return s + "]";
  }
  std::string drain_events(std::string& controls) {
    std::string s = "[";
    controls = "[";
    ev3proto::AgentEvent e;
    while (core_->poll_event(e)) {
      if (e.kind == ev3proto::AgentEvent::Kind::control) {
        if (controls.size() > 1) controls += ',';
        controls += "{\"control\":\"" + std::string(to_string(e.control)) + "\",\"behaviour\":";
        const ev3proto::BehaviourView b = core_->behaviour();
        json_string(controls, b.name);
        controls += ",\"args\":[";
        for (std::size_t i = 0; i < b.arg_count; ++i) {
          if (i) controls += ',';
          json_string(controls, b.arg(i));
        }
        controls += "]}";
        continue;
      }
      if (s.size() > 1) s += ',';
      if (e.kind == ev3proto::AgentEvent::Kind::state)
        s += "{\"state\":\"" + std::string(to_string(e.state)) + "\"}";
      else
        s += "{\"led\":\"" + std::string(to_string(e.led)) + "\"}";
    }
    controls += "]";
    return s + "]";
  }

  /// The robot's check on receipt (spec Refused, CheckReason): the behaviours configured with
  /// "refuse" are refused with that reason, every other one passes.
  ev3proto::BehaviourCheck check() {
    ev3proto::BehaviourCheck c;
    c.ctx = &refusals_;
    c.fn = [](void* ctx, std::string_view name, const std::string_view*, std::size_t,
              ev3proto::CheckReason& why) noexcept {
      const auto& table = *static_cast<const std::map<std::string, std::string, std::less<>>*>(ctx);
      const auto it = table.find(name);
      if (it == table.end()) return true;
      why.set(it->second);
      return false;
    };
    return c;
  }

  std::FILE* trace_ = nullptr;  // --trace FILE
  std::vector<std::string> actions_;  // this input's action objects
  AgentSink sink_;
  std::optional<AgentCore> core_;
  std::map<long long, AgentCore> snaps_;  // save / restore
  std::string model_ = "A";
  std::vector<std::string> beh_names_;
  std::vector<ev3proto::BehaviourSpec> behs_;
  std::map<std::string, std::string, std::less<>> refusals_;  // behaviour -> the check's reason
  long long draw_temp_ = 50000, draw_msgid_ = 1;
  unsigned long long seq_ = 0;
};

}  // namespace

int run_driver(int argc, char** argv) {
  return ev3prog::driver_main<Driver>(argc, argv, "ev3-agent", "agent",
                                      "config, random, recv, advance, event, save, restore, facts");
}

}  // namespace ev3agent
