/// @file agent_sink.hpp
/// @brief The agent core's trace sink in ev3-agent. The program (--trace FILE: one NDJSON line per
///        spec action) and its --driver mode (each action with the variables after it, for the
///        conformance runner) share it, so the binary compiles the agent core once: AgentCore, with
///        the dedupe window's size a run-time setting (AgentConfig::window) rather than a template
///        argument (docs/benchmarks.md, "The EV3 binary").
#pragma once

#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include <ev3proto/agent.hpp>
#include <ev3proto/json.hpp>
#include <ev3proto/node.hpp>
#include <ev3proto/trace.hpp>

namespace ev3agent {

/// The spec variables of the agent (AgentLogic AgentType) as a JSON object (docs/driver.md).
template <typename A>
std::string vars_json(const ev3proto::AgentVars& v, const A& agent) {
  using ev3proto::json_string;
  std::string s = "{\"state\":\"" + std::string(to_string(v.state)) + "\",\"led\":\"" +
                  std::string(to_string(v.led)) + "\",\"id\":" + std::to_string(v.id) + ",\"beh\":";
  json_string(s, v.beh_len == 0 ? std::string_view("NONE") : v.beh_name());
  s += ",\"step\":" + std::to_string(v.step) + ",\"wait\":\"" + std::string(to_string(v.wait)) +
       "\",\"motors\":\"" + (v.motors ? "ON" : "OFF") + "\",\"devOk\":" + (v.dev_ok ? "true" : "false") +
       ",\"silence\":" + std::to_string(v.silence) + ",\"clk\":" + std::to_string(v.clk) +
       ",\"win\":" + ev3proto::window_json(agent.window()) + "}";
  return s;
}

/// A record as the driver's action object: action, args, now, next_msgid, vars after it.
template <typename A>
std::string driver_action(const ev3proto::AgentTraceRecord& r, const A& agent) {
  using ev3proto::json_string;
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
  if (!r.port.empty()) {
    if (!first) s += ',';
    s += "\"p\":";
    json_string(s, r.port);
    first = false;
  }
  if (r.action == ev3proto::Action::Tick) {
    if (!first) s += ',';
    s += "\"ticks\":" + std::to_string(r.ticks);
  }
  return s + "},\"now\":" + std::to_string(r.now) + ",\"next_msgid\":" + std::to_string(agent.next_msgid()) +
         ",\"vars\":" + vars_json(r.after, agent) + "}";
}

/// The trace sink of ev3-agent's agent core.
struct AgentSink {
  static constexpr bool enabled = true;
  /// --trace FILE: gets each record's NDJSON line (node "agent"); empty: none.
  std::function<void(const std::string&)> ndjson;
  /// --driver: each record's action object is appended here; nullptr: none.
  std::vector<std::string>* actions = nullptr;

  template <typename A>
  void record(const ev3proto::AgentTraceRecord& r, const A& agent) {
    if (ndjson) ndjson(ev3proto::to_ndjson(r, agent, "agent"));
    if (actions != nullptr) actions->push_back(driver_action(r, agent));
  }
};

/// The node ev3-agent runs: the agent core traced by AgentSink, the Master core it runs when
/// elected by NdjsonTrace.
using RobotNode = ev3proto::Node<AgentSink, ev3proto::NdjsonTrace>;
/// The agent core: the one instantiation in the binary (the node's, and the --driver mode's).
using AgentCore = RobotNode::AgentCore;

}  // namespace ev3agent
