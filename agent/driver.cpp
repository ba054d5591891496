// ev3-agent --driver: the agent core on a virtual clock, no sockets; NDJSON on stdin/stdout, one
// output line per input line (docs/driver.md). Logs go to stderr. The conformance runner
// (conformance/, `ev3-conformance replay`) drives it with the spec's behaviours.
#include "driver.hpp"

#include <cstdio>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <ev3proto/agent.hpp>
#include <ev3proto/json.hpp>
#include <ev3proto/trace.hpp>
#include <ev3proto/wire.hpp>

#include "ev3prog/driver_json.hpp"
#include "ev3prog/program.hpp"

namespace ev3agent {
namespace {

using ev3prog::Json;
using ev3proto::json_string;
using ev3proto::Millis;

/// The spec variables of the agent (AgentLogic AgentType) as a JSON object.
template <typename A>
std::string vars_json(const ev3proto::AgentVars& v, const A& agent) {
  std::string s = "{\"state\":\"" + std::string(to_string(v.state)) + "\",\"led\":\"" +
                  std::string(to_string(v.led)) + "\",\"id\":" + std::to_string(v.id) + ",\"beh\":";
  json_string(s, v.beh_len == 0 ? std::string_view("NONE") : v.beh_name());
  s += ",\"step\":" + std::to_string(v.step) + ",\"wait\":\"" + std::string(to_string(v.wait)) +
       "\",\"motors\":\"" + (v.motors ? "ON" : "OFF") + "\",\"devOk\":" + (v.dev_ok ? "true" : "false") +
       ",\"silence\":" + std::to_string(v.silence) + ",\"clk\":" + std::to_string(v.clk) +
       ",\"win\":" + ev3proto::window_json(agent.window()) + "}";
  return s;
}

/// Trace sink of the driver: every spec action with its arguments and the full variables after it.
struct DriverSink {
  static constexpr bool enabled = true;
  std::vector<std::string> actions;  // JSON objects of this input's actions
  std::FILE* trace = nullptr;        // --trace FILE: the NdjsonTrace lines too
  template <typename A>
  void record(const ev3proto::AgentTraceRecord& r, const A& agent) {
    std::string s = "{\"action\":\"" + std::string(to_string(r.action)) + "\",\"args\":{";
    bool first = true;
    if (!r.msg.empty()) {
      s += "\"msg\":";
      json_string(s, r.msg);
      first = false;
    }
    if (!r.event.empty()) {
      if (!first) s += ',';
      s += "\"e\":";
      json_string(s, r.event);
      first = false;
    }
    if (r.action == ev3proto::Action::Tick) {
      if (!first) s += ',';
      s += "\"ticks\":" + std::to_string(r.ticks);
    }
    s += "},\"now\":" + std::to_string(r.now) + ",\"next_msgid\":" + std::to_string(agent.next_msgid()) +
         ",\"vars\":" + vars_json(r.after, agent) + "}";
    actions.push_back(std::move(s));
    if (trace != nullptr) {
      const std::string line = ev3proto::to_ndjson(r, agent, "agent");
      std::fwrite(line.data(), 1, line.size(), trace);
      std::fputc('\n', trace);
    }
  }
};

/// The core behind a window size chosen at run time (spec constant Window).
class Core {
 public:
  virtual ~Core() = default;
  virtual void advance(Millis now) = 0;
  virtual std::string recv(std::string_view bytes, ev3proto::Peer from, Millis now) = 0;
  virtual bool event(const std::string& name, const Json& in, Millis now, std::string& err) = 0;
  virtual std::string drain_sent() = 0;
  virtual std::string drain_events(std::string& controls) = 0;
  virtual std::string vars() const = 0;
  virtual Millis deadline() const = 0;
  virtual Millis now() const = 0;
  virtual void save(long long slot) = 0;
  virtual bool restore(long long slot) = 0;
};

template <std::size_t W>
class CoreW final : public Core {
  using A = ev3proto::Agent<DriverSink, W>;

 public:
  CoreW(const ev3proto::AgentConfig& c, Millis now, DriverSink* sink) : a_(c, now, sink) {}

  void advance(Millis now) override { a_.advance(now); }
  std::string recv(std::string_view bytes, ev3proto::Peer from, Millis now) override {
    return std::string(to_string(a_.handle_datagram(bytes, from, now).action));
  }
  bool event(const std::string& name, const Json& in, Millis now, std::string& err) override {
    if (name == "action_ok") return a_.action_ok(now);
    if (name == "action_failed") return a_.action_failed(now);
    if (name == "battery_low") return a_.battery_low(now);
    if (name == "action_interrupted") {
      const std::string w = in["warning"].str("OBSTACLE_DETECTED");
      if (w != "OBSTACLE_DETECTED" && w != "PROXIMITY_ALERT") {
        err = "unknown warning '" + w + "' (OBSTACLE_DETECTED or PROXIMITY_ALERT)";
        return false;
      }
      return a_.action_interrupted(
          w == "OBSTACLE_DETECTED" ? ev3proto::Warning::OBSTACLE_DETECTED : ev3proto::Warning::PROXIMITY_ALERT,
          now);
    }
    if (name == "sensor_report") {
      std::vector<std::string> vals;
      for (const Json& v : in["values"].a) vals.push_back(v.str());
      if (vals.empty()) vals.push_back("value");
      std::vector<std::string_view> views(vals.begin(), vals.end());
      return a_.sensor_report(in["port"].str("port"), in["mode"].str("mode"), views.data(), views.size(), now);
    }
    if (name == "device_unplugged" || name == "device_plugged") {
      const auto bits = static_cast<std::uint32_t>(in["devices"].num(1));
      return name == "device_unplugged" ? a_.device_unplugged(bits, now) : a_.device_plugged(bits, now);
    }
    err = "unknown event '" + name + "'";
    return false;
  }
  std::string drain_sent() override {
    std::string s = "[";
    ev3proto::Transmit t;
    while (a_.poll_transmit(t)) {
      if (s.size() > 1) s += ',';
      s += "{\"to\":\"" + std::string(to_string(t.dest)) + "\"";
      if (t.dest == ev3proto::Dest::master) s += ",\"peer\":" + std::to_string(t.peer);
      s += ",\"text\":";
      json_string(s, t.bytes);
      s += ",\"hex\":\"" + ev3prog::hex(t.bytes) + "\"}";
    }
    return s + "]";
  }
  std::string drain_events(std::string& controls) override {
    std::string s = "[";
    controls = "[";
    ev3proto::AgentEvent e;
    while (a_.poll_event(e)) {
      if (e.kind == ev3proto::AgentEvent::Kind::control) {
        if (controls.size() > 1) controls += ',';
        controls += "{\"control\":\"" + std::string(to_string(e.control)) + "\",\"behaviour\":";
        const ev3proto::BehaviourView b = a_.behaviour();
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
  std::string vars() const override { return vars_json(a_.vars(), a_); }
  Millis deadline() const override { return a_.next_deadline(); }
  Millis now() const override { return a_.now(); }
  void save(long long slot) override { snaps_.insert_or_assign(slot, a_); }
  bool restore(long long slot) override {
    auto it = snaps_.find(slot);
    if (it == snaps_.end()) return false;
    a_ = it->second;
    return true;
  }

 private:
  A a_;
  std::map<long long, A> snaps_;
};

class Driver {
 public:
  explicit Driver(std::FILE* trace) { sink_.trace = trace; }

  int run() {
    return ev3prog::run_driver_lines(sink_.trace, seq_, [this](const std::string& line) { return handle(line); });
  }

  // Below: what ev3prog::dispatch_input() asks of a driver (configure() among it), then output().
  bool configure(const Json& in, std::string& err) {
    ev3proto::AgentConfig c;
    const Json& t = in["timers"];
    struct {
      const char* name;
      ev3proto::Timer timer;
    } const rows[] = {{"sync", ev3proto::Timer::sync},
                      {"heartbeat", ev3proto::Timer::heartbeat},
                      {"loss", ev3proto::Timer::loss},
                      {"paused", ev3proto::Timer::paused},
                      {"relay_retry", ev3proto::Timer::relay_retry},
                      {"backoff", ev3proto::Timer::backoff},
                      {"backoff_step", ev3proto::Timer::backoff_step},
                      {"candidate", ev3proto::Timer::candidate}};
    for (const auto& r : rows)
      if (t.has(r.name)) c.timers.set(r.timer, static_cast<Millis>(t[r.name].num(1)));
    // Relay and election (Election.tla): {"enabled", "score", "epoch", "voted_for"}.
    const Json& el = in["election"];
    c.election.enabled = el["enabled"].boolean(false);
    if (el.has("score")) c.election.score = static_cast<std::uint32_t>(el["score"].num(0));
    c.election.epoch = static_cast<std::uint32_t>(el["epoch"].num(1));
    c.election.voted_for = static_cast<std::uint16_t>(el["voted_for"].num(0));
    if (!c.timers.valid()) {
      err = "timers: paused must be greater than loss";
      return false;
    }
    model_ = in["model"].str("A");
    beh_names_.clear();
    behs_.clear();
    if (in["behaviours"].kind == Json::Kind::array) {
      for (const Json& b : in["behaviours"].a) beh_names_.push_back(b["name"].str());
      std::size_t i = 0;
      for (const Json& b : in["behaviours"].a)
        behs_.push_back({beh_names_[i++], static_cast<std::uint32_t>(b["devices"].num(0))});
    } else {
      beh_names_.push_back("wait");
      behs_.push_back({beh_names_[0], 0});
    }
    c.caps = {model_, behs_.data(), behs_.size(), static_cast<std::uint32_t>(in["devices"].num(1))};
    if (in.has("temp_id")) draw_temp_ = in["temp_id"].num();
    if (in.has("first_msgid")) draw_msgid_ = in["first_msgid"].num();
    c.temp_id = static_cast<std::uint16_t>(draw_temp_);
    c.first_msgid = static_cast<std::uint32_t>(draw_msgid_);
    const long long w = in["window"].num(50);
    const Millis now = static_cast<Millis>(in["now"].num(0));
    switch (w) {
      case 1: core_ = std::make_unique<CoreW<1>>(c, now, &sink_); break;
      case 2: core_ = std::make_unique<CoreW<2>>(c, now, &sink_); break;
      case 3: core_ = std::make_unique<CoreW<3>>(c, now, &sink_); break;
      case 4: core_ = std::make_unique<CoreW<4>>(c, now, &sink_); break;
      case 8: core_ = std::make_unique<CoreW<8>>(c, now, &sink_); break;
      case 16: core_ = std::make_unique<CoreW<16>>(c, now, &sink_); break;
      case 50: core_ = std::make_unique<CoreW<50>>(c, now, &sink_); break;
      default: err = "window must be one of 1 2 3 4 8 16 50"; return false;
    }
    std::fprintf(stderr, "ev3-agent --driver: configured (model %s, temporary id %lld, window %lld, now %llu)\n",
                 model_.c_str(), draw_temp_, w, static_cast<unsigned long long>(now));
    return true;
  }

  std::string handle(const std::string& line) { return ev3prog::dispatch_input(*this, line); }

  std::string error(const std::string& msg) { return ev3prog::driver_error("ev3-agent --driver", seq_, msg); }
  void clear_actions() { sink_.actions.clear(); }
  bool has_core() const { return core_ != nullptr; }
  Millis core_now() const { return core_->now(); }
  void core_advance(Millis to) { core_->advance(to); }
  void core_recv(const std::string& bytes, const Json& in, Millis now) {
    core_->recv(bytes, static_cast<ev3proto::Peer>(in["from"].num(1)), now);
  }
  /// "random" (the ids and msgids the agent will draw) needs no core.
  bool early(const std::string& type, const Json& in, std::string& reply) {
    if (type != "random") return false;
    if (in.has("temp_id")) draw_temp_ = in["temp_id"].num();
    if (in.has("first_msgid")) draw_msgid_ = in["first_msgid"].num();
    reply = output(true);
    return true;
  }
  std::string own(const std::string& type, const Json& in, Millis now) {
    std::string err;
    if (type == "event") {
      const bool ok = core_->event(in["event"].str(), in, now, err);
      if (!err.empty()) return error(err);
      return output(ok);
    }
    if (type == "save") {
      core_->save(in["slot"].num());
      return output(true);
    }
    if (type == "restore") {
      if (!core_->restore(in["slot"].num())) return error("no snapshot in that slot");
      sink_.actions.clear();
      core_->drain_sent();
      std::string c;
      core_->drain_events(c);
      return output(true);
    }
    return error("unknown input type '" + type + "'");
  }
  std::string output(bool taken) {
    if (!core_) return ev3prog::output_start(seq_, taken) + "}";
    std::string s = ev3prog::output_start(seq_, taken, core_->now(), sink_.actions) + ",\"sent\":" + core_->drain_sent();
    std::string controls;
    s += ",\"events\":" + core_->drain_events(controls);
    s += ",\"controls\":" + controls;
    const Millis d = core_->deadline();
    s += ",\"deadline\":" + (d == ev3proto::Agent<>::kNever ? std::string("null") : std::to_string(d));
    s += ",\"vars\":" + core_->vars() + "}";
    return s;
  }

 private:
  DriverSink sink_;
  std::unique_ptr<Core> core_;
  std::string model_ = "A";
  std::vector<std::string> beh_names_;
  std::vector<ev3proto::BehaviourSpec> behs_;
  long long draw_temp_ = 50000, draw_msgid_ = 1;
  unsigned long long seq_ = 0;
};

}  // namespace

int run_driver(int argc, char** argv) {
  return ev3prog::driver_main<Driver>(argc, argv, "ev3-agent", "agent", "config, random, recv, advance, event, save, restore");
}

}  // namespace ev3agent
