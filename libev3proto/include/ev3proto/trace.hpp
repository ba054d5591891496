/// @file trace.hpp
/// @brief Trace sinks for the cores: one NDJSON line per spec action (docs/core.md, "Trace").
///
/// Host-side (tests, the conformance runner, a debugging build of the firmware): this header uses
/// std::string and may allocate. The agent core itself never includes it; an Agent<NoTrace> carries
/// no trace code at all.
///
/// A line: {"node":"agent","action":"RecvStart","args":{"msg":"1:7:5:8"},"now":1234,
///          "changed":{"state":"WORKING","led":"GREEN","motors":"ON"}}
/// Variable names and values are the spec's (AgentLogic AgentType; Fleet master fields).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "agent.hpp"
#include "core.hpp"
#include "json.hpp"
#include "master.hpp"

namespace ev3proto {

namespace trace_detail {

/// Appends `"key":` (with a leading comma unless @p first).
inline void json_key(std::string& out, std::string_view key, bool& first) {
  if (!first) out += ',';
  first = false;
  json_string(out, key);
  out += ':';
}

/// The start of a record's line, the same for agent and master: `{"node":..,"action":..,"args":{`
/// and the datagram received as args.msg (when there is one); the args object is left open for
/// more (@p afirst: whether none was written yet).
inline std::string record_head(std::string_view node, Action action, std::string_view msg, bool& afirst) {
  std::string s = "{";
  bool first = true;
  json_key(s, "node", first);
  json_string(s, node);
  json_key(s, "action", first);
  json_string(s, to_string(action));
  json_key(s, "args", first);
  s += '{';
  afirst = true;
  if (!msg.empty()) {
    json_key(s, "msg", afirst);
    json_string(s, msg);
  }
  return s;
}

/// Closes the args and writes the record's time: `},"now":..`.
inline void record_now(std::string& s, Millis now) {
  s += "},\"now\":";
  s += std::to_string(now);
}

/// The "changed" object of a record: the variables whose value differs before and after.
class Changed {
 public:
  explicit Changed(std::string& s) : s_(s) {}
  /// @p k as the text @p v.
  void str(std::string_view k, std::string_view v) {
    json_key(s_, k, first_);
    json_string(s_, v);
  }
  /// @p k as the number @p v.
  void num(std::string_view k, std::uint64_t v) {
    json_key(s_, k, first_);
    s_ += std::to_string(v);
  }
  /// @p k as the JSON @p v (written as it is).
  void json(std::string_view k, std::string_view v) {
    json_key(s_, k, first_);
    s_ += v;
  }
  /// num(k, after) when @p after differs from @p before.
  void num(std::string_view k, std::uint64_t before, std::uint64_t after) {
    if (after != before) num(k, after);
  }

 private:
  std::string& s_;
  bool first_ = true;
};

}  // namespace trace_detail

/// The window as the spec's win: [{"src":..,"msgid":..,"ans":{"type":"ACK","src":..,"ref":..}}].
template <typename W>
std::string window_json(const W& win) {
  std::string s = "[";
  bool first = true;
  win.for_each([&](std::uint16_t src, std::uint32_t msgid, const StoredAnswer& a) {
    if (!first) s += ',';
    first = false;
    s += "{\"src\":" + std::to_string(src) + ",\"msgid\":" + std::to_string(msgid) +
         ",\"ans\":{\"type\":\"" + (a.ack ? "ACK" : "NOT") + "\",\"src\":" + std::to_string(a.src) +
         ",\"ref\":" + std::to_string(a.ref);
    if (!a.ack) {
      s += ",\"reason\":";
      json_string(s, a.reason_text());
    }
    s += "}}";
  });
  return s + "]";
}

/// Formats an agent trace record as one NDJSON line (no newline). Only the variables that changed
/// appear under "changed"; @p node names the agent ("agent", "agent3").
template <typename A>
std::string to_ndjson(const AgentTraceRecord& r, const A& agent, std::string_view node = "agent") {
  using trace_detail::json_key;
  bool afirst = true;
  std::string s = trace_detail::record_head(node, r.action, r.msg, afirst);
  if (!r.event.empty()) {
    json_key(s, "e", afirst);
    json_string(s, r.event);
  }
  if (!r.port.empty()) {
    json_key(s, "p", afirst);
    json_string(s, r.port);
  }
  if (!r.check.empty()) {
    json_key(s, "check", afirst);
    json_string(s, r.check);
  }
  if (r.action == Action::Tick) {
    json_key(s, "ticks", afirst);
    s += std::to_string(r.ticks);
  }
  if (r.action == Action::ApplyCommand) {
    json_key(s, "cmd", afirst);
    json_string(s, to_string(r.cmd));
  }
  trace_detail::record_now(s, r.now);
  s += ",\"changed\":{";
  trace_detail::Changed c(s);
  const AgentVars& b = r.before;
  const AgentVars& a = r.after;
  if (a.state != b.state) c.str("state", to_string(a.state));
  if (a.led != b.led) c.str("led", to_string(a.led));
  c.num("id", b.id, a.id);
  if (a.beh_name() != b.beh_name()) c.str("beh", a.beh_len == 0 ? "NONE" : a.beh_name());
  c.num("step", b.step, a.step);
  if (a.wait != b.wait) c.str("wait", to_string(a.wait));
  if (a.motors != b.motors) c.str("motors", a.motors ? "ON" : "OFF");
  if (a.dev_ok != b.dev_ok) c.json("devOk", a.dev_ok ? "true" : "false");
  c.num("silence", b.silence, a.silence);
  c.num("clk", b.clk, a.clk);
  if (a.win_rev != b.win_rev) c.json("win", window_json(agent.window()));
  c.num("msgid", b.msgid, a.msgid);  // the next msgid: this record sent [b.msgid, a.msgid)
  c.num("made", b.made, a.made);     // Reports.tla: a report made (Make)
  c.num("lo", b.lo, a.lo);           // Reports.tla: the PC's acknowledgement freed (TakeAck)
  if (a.election) {  // Election.tla's variables of this agent
    auto life = [](const AgentVars& v) {
      return v.role == ElectionRole::master ? std::string_view("MASTER")
             : v.role == ElectionRole::candidate ? std::string_view("CANDIDATE")
                                         : to_string(v.state);
    };
    auto ids = [&](std::string_view k, std::size_t n, auto get) {
      std::string v = "[";
      for (std::size_t i = 0; i < n; ++i) v += (i ? "," : "") + std::to_string(get(i));
      c.json(k, v + "]");
    };
    if (life(a) != life(b)) c.str("life", life(a));
    c.num("epoch", b.epoch, a.epoch);
    c.num("votedFor", b.voted_for, a.voted_for);
    c.num("leader", b.leader, a.leader);
    c.num("following", b.following, a.following);
    c.num("via", b.via, a.via);
    const auto& el = agent.election();
    if (a.relay_rev != b.relay_rev) {
      ids("relays", el.relays.size(), [&](std::size_t i) { return el.relays.id(i); });
      ids("offered", el.offered.size(), [&](std::size_t i) { return el.offered.id(i); });
      ids("votes", el.votes.size(), [&](std::size_t i) { return el.votes[i]; });
      ids("prevotes", el.prevotes.size(), [&](std::size_t i) { return el.prevotes[i]; });
    }
    if (a.members_rev != b.members_rev)
      ids("members", el.members.size(), [&](std::size_t i) { return el.members[i]; });
    c.num("mepoch", b.mepoch, a.mepoch);
    c.num("floor", b.floor, a.floor);
  }
  s += "}}";
  return s;
}

/// Formats a master trace record as one NDJSON line (no newline); "changed" holds the master's
/// variables that changed: reg (master.reg), nextId, msgid (and the election's; a PCTake record:
/// args.stored, and rec {agent, stored} when the sender's record grew).
inline std::string to_ndjson(const MasterTraceRecord& r, std::string_view node = "master") {
  bool afirst = true;
  std::string s = trace_detail::record_head(node, r.action, r.msg, afirst);
  if (r.rec_agent != 0) {  // PCTake: the sender's last number recorded, before
    trace_detail::json_key(s, "stored", afirst);
    s += std::to_string(r.rec_before);
  }
  trace_detail::record_now(s, r.now);
  if (r.msgid_after != r.msgid_before) {
    // Where the msgids this record sent start (changed.msgid is where they end): a master's first
    // msgid comes from its state file or the wall clock (msgids.hpp), and a check needs it.
    s += ",\"msgid_from\":" + std::to_string(r.msgid_before);
  }
  s += ",\"changed\":{";
  trace_detail::Changed c(s);
  if (r.reg_after != r.reg_before) c.json("reg", r.reg_after);
  c.num("nextId", r.next_id_before, r.next_id_after);
  c.num("msgid", r.msgid_before, r.msgid_after);
  if (r.life_after != r.life_before) c.str("life", r.life_after);
  c.num("epoch", r.epoch_before, r.epoch_after);
  if (r.votes_after != r.votes_before) c.json("votes", r.votes_after);
  if (r.members_after != r.members_before) c.json("members", r.members_after);
  c.num("mepoch", r.mepoch_before, r.mepoch_after);
  if (r.rec_agent != 0 && r.rec_after != r.rec_before)
    c.json("rec", "{\"agent\":" + std::to_string(r.rec_agent) + ",\"stored\":" + std::to_string(r.rec_after) + "}");
  s += "}}";
  return s;
}

/// A trace sink that turns every record into an NDJSON line and hands it to a callback (or keeps
/// it in @c lines when no callback is set).
class NdjsonTrace {
 public:
  /// Tracing on.
  static constexpr bool enabled = true;

  /// A sink labelling its records with @p node.
  explicit NdjsonTrace(std::string node = "agent") : node_(std::move(node)) {}

  /// Sends each line to @p out instead of keeping it.
  void set_output(std::function<void(const std::string&)> out) { out_ = std::move(out); }

  /// Agent record (called by Agent).
  template <typename A>
  void record(const AgentTraceRecord& r, const A& agent) {
    emit(to_ndjson(r, agent, node_));
  }

  /// Master record (called by Master).
  void record(const MasterTraceRecord& r) { emit(to_ndjson(r, node_)); }

  /// The lines kept so far (when no output callback is set).
  std::vector<std::string> lines;

 private:
  void emit(std::string line) {
    if (out_)
      out_(line);
    else
      lines.push_back(std::move(line));
  }
  std::string node_;
  std::function<void(const std::string&)> out_;
};

}  // namespace ev3proto
