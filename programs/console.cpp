#include "ev3prog/console.hpp"

#include <cstdio>

#include <ev3proto/behaviour/request.hpp>
#include <ev3proto/json.hpp>
#include <ev3proto/rules.hpp>

#include "ev3io/cli.hpp"

namespace ev3prog {

using ev3proto::MsgType;
using Kind = ev3proto::OperatorEvent::Kind;

namespace {
std::vector<std::string_view> words(std::string_view s) {
  std::vector<std::string_view> w;
  std::size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && (s[i] == ' ' || s[i] == '\t' || s[i] == '\r')) ++i;
    const std::size_t b = i;
    while (i < s.size() && s[i] != ' ' && s[i] != '\t' && s[i] != '\r') ++i;
    if (i > b) w.push_back(s.substr(b, i - b));
  }
  return w;
}

bool parse_id(std::string_view w, std::uint16_t& id) {
  if (w == "all") {
    id = 0;
    return true;
  }
  std::uint64_t v = 0;
  if (!ev3io::to_uint(w, 1, 65535, v)) return false;
  id = static_cast<std::uint16_t>(v);
  return true;
}

std::string fmt_age(Millis ms) {
  char b[32];
  std::snprintf(b, sizeof b, "%.1fs ago", static_cast<double>(ms) / 1000.0);
  return b;
}

std::string pad(std::string s, std::size_t n) {
  if (s.size() > n) s = s.substr(0, n - 1) + "~";
  s.append(n - s.size(), ' ');
  return s;
}
}  // namespace

std::string console_help() {
  return "commands: list | behaviour ID|all NAME [key=value ...] | behaviour ID|all custom @FILE.bhv "
         "[key=value ...] | start|stop|pause|resume|standby|continue|restart ID|all | "
         "rule explore-exploit COLOUR [key=value ...] | rule explore-exploit off | wait SECONDS (scripts) | "
         "help | quit";
}

std::string parse_console_line(std::string_view line, ConsoleCommand& out) {
  out = ConsoleCommand{};
  const std::vector<std::string_view> w = words(line);
  if (w.empty() || w[0][0] == '#') return {};
  const std::string_view cmd = w[0];
  if (cmd == "list" || cmd == "help" || cmd == "quit" || cmd == "exit") {
    if (w.size() != 1) return "'" + std::string(cmd) + "' takes no argument";
    out.kind = cmd == "list" ? ConsoleCommand::Kind::list
               : cmd == "help" ? ConsoleCommand::Kind::help
                               : ConsoleCommand::Kind::quit;
    return {};
  }
  if (cmd == "wait") {
    if (w.size() != 2 || !ev3io::to_double(w[1], 0, 86400, out.seconds))
      return "bad argument: wait takes SECONDS (a number >= 0)";
    out.kind = ConsoleCommand::Kind::wait;
    return {};
  }
  static const std::pair<std::string_view, MsgType> kSimple[] = {
      {"start", MsgType::START},     {"stop", MsgType::STOP},         {"pause", MsgType::PAUSE},
      {"resume", MsgType::RESUME},   {"standby", MsgType::STANDBY},   {"continue", MsgType::CONTINUE},
      {"restart", MsgType::RESTART}};
  for (const auto& s : kSimple) {
    if (cmd != s.first) continue;
    if (w.size() != 2) return "bad argument: " + std::string(cmd) + " takes ID|all";
    if (!parse_id(w[1], out.agent))
      return "bad agent id '" + std::string(w[1]) + "' (expected a number or all)";
    out.kind = ConsoleCommand::Kind::send;
    out.command = ev3proto::Command::simple(s.second);
    return {};
  }
  if (cmd == "behaviour" || cmd == "behavior") {
    if (w.size() < 3) return "bad argument: behaviour takes ID|all NAME [key=value ...]";
    if (!parse_id(w[1], out.agent))
      return "bad agent id '" + std::string(w[1]) + "' (expected a number or all)";
    if (w[2].size() > 32) return "bad argument: behaviour name longer than 32 bytes";
    std::size_t first = 3;
    if (w[2] == ev3proto::behaviour::kCustom) {
      if (w.size() < 4 || w[3].size() < 2 || w[3][0] != '@')
        return "bad argument: custom takes @FILE.bhv (the definition's file) [key=value ...]";
      out.file = std::string(w[3].substr(1));
      first = 4;
    }
    std::vector<std::string> args;
    for (std::size_t i = first; i < w.size(); ++i) {
      const std::size_t eq = w[i].find('=');
      if (eq == std::string_view::npos || eq == 0)
        return "bad argument '" + std::string(w[i]) + "' (expected key=value)";
      args.emplace_back(w[i]);
    }
    if (args.size() > ev3proto::kMaxParams - 1) return "bad argument: at most 31 key=value arguments";
    out.kind = ConsoleCommand::Kind::send;
    out.command = ev3proto::Command::assign(std::string(w[2]), std::move(args));
    return {};
  }
  if (cmd == "rule") {
    if (w.size() < 3 || w[1] != "explore-exploit")
      return "bad argument: rule takes explore-exploit COLOUR [key=value ...] or explore-exploit off";
    out.kind = ConsoleCommand::Kind::rule;
    if (w[2] == "off") {
      if (w.size() != 3) return "bad argument: rule explore-exploit off takes nothing more";
      return {};
    }
    ev3proto::ExploreExploit probe;
    if (std::string e = probe.switch_on(w[2]); !e.empty()) return "bad argument: " + e;
    out.colour = std::string(w[2]);
    for (std::size_t i = 3; i < w.size(); ++i) {
      if (w[i].find('=') == std::string_view::npos || w[i][0] == '=')
        return "bad argument '" + std::string(w[i]) + "' (expected key=value)";
      out.rule_args.emplace_back(w[i]);
    }
    return {};
  }
  return "unknown command '" + std::string(cmd) + "' (" + console_help() + ")";
}

std::string console_command(std::string_view line, ConsoleCommand& out) {
  std::string err = parse_console_line(line, out);
  return err.empty() ? prepare_behaviour(out) : err;
}

std::string state_text(const ev3proto::RegistryEntry& e) {
  if (!e.synced) return "SYNCING";
  if (!e.has_state) return "SYNCED";
  return std::string(ev3proto::to_string(e.state));
}

std::string FleetView::on_event(const ev3proto::OperatorEvent& e, const std::string& address, Millis now) {
  const std::string who = "agent " + std::to_string(e.agent);
  const std::string cmd(ev3proto::to_string(e.command));
  AgentInfo* info = nullptr;
  if (e.kind != Kind::unknown_agent) {
    info = &info_[e.agent];
    if (!address.empty()) info->address = address;
  }
  switch (e.kind) {
    case Kind::registered:
      info->action = "-";
      return who + " registered (announced " + e.text + ") at " + address;
    case Kind::acked:
      info->action = cmd + " acked";
      info->answer = info->action;
      return who + ": " + cmd + " acknowledged (ACK)";
    case Kind::refused:
      info->action = cmd + " refused";
      info->answer = info->action;
      return who + ": " + cmd + " refused (NOT): " + e.text;
    case Kind::timed_out:
      info->action = cmd + " timed out";
      info->answer = info->action;
      return who + ": " + cmd + " timed out (no answer)";
    case Kind::unknown_agent: return "error: unknown agent id " + std::to_string(e.agent);
    case Kind::dropped:
      lost_.push_back(LostAgent{e.agent, info->address, now});
      info_.erase(e.agent);
      return who + " lost (not heard for the agent timeout)";
    case Kind::state: return who + ": state " + e.text;
    case Kind::reports_dropped:
      return who + ": reports " + std::to_string(e.seq) + "-" + std::to_string(e.last) +
             " dropped by the robot's bound (REPORT_DROPPED)";
    case Kind::reports_skipped:
      return who + ": reports " + std::to_string(e.seq) + "-" + std::to_string(e.last) +
             " not here: the robot no longer held them when it reported here";
    case Kind::report: {
      std::string t = e.text;
      for (char& c : t)
        if (c == ':') c = ' ';
      if (e.command == MsgType::EVENT && e.text.rfind("BATTERY", 0) == 0) {
        const std::size_t colon = e.text.find(':');
        info->battery = colon == std::string::npos ? e.text : e.text.substr(colon + 1);
      }
      if (e.command == MsgType::EVENT && e.text == "LEAVING") {
        info->action = "LEAVING";
        return who + " is leaving (EVENT LEAVING)";
      }
      info->action = cmd + (t.empty() ? "" : " " + t);
      info->report = info->action;
      info->report_at = now;
      if (e.command == MsgType::ACTION_OK || e.command == MsgType::ACTION_INTERR || e.command == MsgType::ACTION_ERR)
        info->step = e.text.substr(0, e.text.find(':'));
      return who + ": " + cmd + (t.empty() ? "" : " " + t);
    }
  }
  return who;
}

std::string report_summary(const ev3proto::ReportRecord& r) {
  if (r.next == 0) return "-";
  std::string s = r.stored() < r.first ? "none from " + std::to_string(r.first)
                                       : std::to_string(r.first) + "-" + std::to_string(r.stored());
  std::vector<std::string> notes;
  if (r.dropped) notes.push_back(std::to_string(r.dropped) + " dropped");
  if (r.skipped) notes.push_back(std::to_string(r.skipped) + " skipped");
  if (r.ahead) notes.push_back("gap " + std::to_string(r.next) + "-" + std::to_string(r.ahead - 1));
  for (std::size_t i = 0; i < notes.size(); ++i) s += (i ? ", " : " (") + notes[i];
  return notes.empty() ? s : s + ")";
}

std::string report_json(const ev3proto::ReportRecord& r) {
  return "{\"first\":" + std::to_string(r.first) + ",\"last\":" + std::to_string(r.stored()) +
         ",\"recorded\":" + std::to_string(r.reports) + ",\"dropped\":" + std::to_string(r.dropped) +
         ",\"skipped\":" + std::to_string(r.skipped) + ",\"gap\":" +
         (r.ahead ? "[" + std::to_string(r.next) + "," + std::to_string(r.ahead - 1) + "]" : std::string("null")) + "}";
}

std::vector<std::string> FleetView::table(const std::map<std::uint16_t, ev3proto::RegistryEntry>& reg,
                                          const Counters& drops, Millis now,
                                          const std::map<std::uint16_t, ev3proto::ReportRecord>& records) const {
  std::vector<std::string> t;
  t.push_back(pad("ID", 6) + pad("ADDRESS", 22) + pad("STATE", 9) + pad("HEARD", 10) + pad("BEHAVIOUR", 11) +
              pad("STEP", 12) + pad("LAST REPORT", 46) + pad("COMMAND", 20) + pad("BATTERY", 9) + "REPORTS");
  for (const auto& kv : reg) {
    const ev3proto::RegistryEntry& e = kv.second;
    auto it = info_.find(kv.first);
    const AgentInfo empty;
    const AgentInfo& i = it == info_.end() ? empty : it->second;
    t.push_back(pad(std::to_string(kv.first), 6) + pad(i.address, 22) + pad(state_text(e), 9) +
                pad(fmt_age(now > e.heard ? now - e.heard : 0), 10) +
                pad(e.behaviour.empty() ? "-" : e.behaviour, 11) + pad(i.step, 12) +
                pad(i.report == "-" ? "-" : i.report + " (" + fmt_age(now - i.report_at) + ")", 46) +
                pad(i.answer, 20) + pad(i.battery, 9) +
                (records.count(kv.first) ? report_summary(records.at(kv.first)) : std::string("-")));
  }
  if (reg.empty()) t.push_back("(no agents yet)");
  std::string d = "drops:";
  if (drops.empty()) d += " none";
  for (const auto& kv : drops) d += " " + kv.first + "=" + std::to_string(kv.second);
  t.push_back(d);
  if (!lost_.empty()) {
    std::string l = "lost:";
    for (const LostAgent& a : lost_) l += " " + std::to_string(a.id) + " (" + fmt_age(now - a.at) + ")";
    t.push_back(l);
  }
  return t;
}

std::string FleetView::status_json(const std::map<std::uint16_t, ev3proto::RegistryEntry>& reg,
                                   const Counters& drops, const std::string& listening, std::uint16_t next_id,
                                   Millis now, Millis start,
                                   const std::map<std::uint16_t, ev3proto::ReportRecord>& records) const {
  std::string s = "{\"uptime_ms\":" + std::to_string(now - start) + ",\"listening\":" + ev3proto::json_quote(listening) +
                  ",\"next_id\":" + std::to_string(next_id) + ",\"election\":" +
                  (election_role_.empty() ? std::string("null")
                                          : "{\"role\":" + ev3proto::json_quote(election_role_) +
                                                ",\"epoch\":" + std::to_string(election_epoch_) + "}") +
                  ",\"agents\":[";
  bool first = true;
  for (const auto& kv : reg) {
    const ev3proto::RegistryEntry& e = kv.second;
    auto it = info_.find(kv.first);
    const AgentInfo empty;
    const AgentInfo& i = it == info_.end() ? empty : it->second;
    if (!first) s += ',';
    first = false;
    s += "{\"id\":" + std::to_string(kv.first) + ",\"announced\":" + std::to_string(e.ann) +
         ",\"model\":" + (e.model.empty() ? std::string("null") : ev3proto::json_quote(e.model)) +
         ",\"devices\":" + (e.model.empty() ? std::string("null") : ev3proto::json_list(e.devices)) +
         ",\"address\":" + ev3proto::json_quote(i.address) + ",\"synced\":" + (e.synced ? "true" : "false") +
         ",\"state\":" + ev3proto::json_quote(state_text(e)) + ",\"led\":" +
         (e.synced && e.has_state ? ev3proto::json_quote(ev3proto::to_string(ev3proto::led_of(ev3proto::state_of(e.state))))
                                  : std::string("null")) +
         ",\"via\":" + (e.via == 0 ? std::string("null") : std::to_string(e.via)) +
         ",\"last_heard_ms_ago\":" + std::to_string(now > e.heard ? now - e.heard : 0) +
         ",\"behaviour\":" + (e.behaviour.empty() ? std::string("null") : ev3proto::json_quote(e.behaviour)) +
         ",\"action\":" + ev3proto::json_quote(i.action.empty() ? "-" : i.action) +
         ",\"step\":" + (i.step == "-" ? std::string("null") : ev3proto::json_quote(i.step)) +
         ",\"last_report\":" + (i.report == "-" ? std::string("null") : ev3proto::json_quote(i.report)) +
         ",\"battery\":" + (i.battery == "-" ? std::string("null") : ev3proto::json_quote(i.battery)) +
         ",\"pending\":" + ev3proto::json_quote(e.job()) + ",\"queued\":" + std::to_string(e.queue.size()) + "}";
  }
  s += "],\"lost\":[";
  first = true;
  for (const LostAgent& a : lost_) {
    if (!first) s += ',';
    first = false;
    s += "{\"id\":" + std::to_string(a.id) + ",\"address\":" + ev3proto::json_quote(a.address) +
         ",\"lost_ms_ago\":" + std::to_string(now - a.at) + "}";
  }
  s += "],\"reports\":{";
  first = true;
  for (const auto& kv : records) {
    if (!first) s += ',';
    first = false;
    s += "\"" + std::to_string(kv.first) + "\":" + report_json(kv.second);
  }
  s += "},\"drops\":{";
  first = true;
  for (const auto& kv : drops) {
    if (!first) s += ',';
    first = false;
    s += ev3proto::json_quote(kv.first) + ":" + std::to_string(kv.second);
  }
  return s + "}}";
}

std::string FleetView::set_rule(const ConsoleCommand& c) {
  if (c.colour.empty()) {
    explore_exploit_.switch_off();
    return "rule explore-exploit off";
  }
  const std::string err = explore_exploit_.switch_on(c.colour, c.rule_args);
  if (!err.empty()) return "error: " + err;
  std::string args;
  for (const std::string& a : c.rule_args) args += " " + a;
  return "rule explore-exploit on: an exploring robot whose colour sensor reports " + c.colour +
         " gets behaviour exploit colour=" + c.colour + args;
}

std::optional<FleetView::RuleCommand> FleetView::follow_rules(
    const ev3proto::OperatorEvent& e, const std::map<std::uint16_t, ev3proto::RegistryEntry>& reg) {
  const auto it = reg.find(e.agent);
  if (it == reg.end()) return std::nullopt;
  std::optional<ev3proto::Command> c = explore_exploit_.on_report(e, it->second);  // once per explore run
  if (!c) return std::nullopt;
  std::string args;
  for (const std::string& a : c->args) args += " " + a;
  return RuleCommand{e.agent, std::move(*c),
                     "rule explore-exploit: agent " + std::to_string(e.agent) + " is on " +
                         explore_exploit_.colour() + ": behaviour " + std::to_string(e.agent) + " exploit" + args};
}

}  // namespace ev3prog
