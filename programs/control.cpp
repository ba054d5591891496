#include "ev3prog/control.hpp"

#include <algorithm>
#include <iterator>

#include <ev3proto/json.hpp>

namespace ev3prog {

using ev3proto::OperatorEvent;

ControlLine parse_control_line(std::string_view line, bool json_default) {
  ControlLine out;
  out.json = json_default;
  std::size_t i = line.find_first_not_of(" \t");
  if (i != std::string_view::npos && line.substr(i, 6) == "--json" &&
      (line.size() == i + 6 || line[i + 6] == ' ' || line[i + 6] == '\t')) {
    out.json = true;
    line.remove_prefix(i + 6);
  }
  while (!line.empty() && (line.front() == ' ' || line.front() == '\t')) line.remove_prefix(1);
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);  // a client that ends lines with CRLF
  out.command = std::string(line);
  return out;
}

std::string control_ok(bool json, const std::string& text) {
  if (!json) return text.empty() ? "ok" : text;
  return "{\"ok\":true,\"answer\":" + ev3proto::json_quote(text.empty() ? "ok" : text) + "}";
}

std::string control_error(bool json, const std::string& text) {
  if (!json) return "error: " + text;
  return "{\"ok\":false,\"error\":" + ev3proto::json_quote(text) + "}";
}

std::string control_list(bool json, const std::vector<std::string>& table, const std::string& status_json) {
  if (json) return "{\"ok\":true,\"status\":" + status_json + "}";
  std::string s;
  for (const std::string& row : table) {
    const std::size_t end = row.find_last_not_of(' ');
    if (!s.empty()) s += " | ";
    s += row.substr(0, end == std::string::npos ? 0 : end + 1);
  }
  return s;
}

bool ControlAnswers::Waiting::done() const {
  return std::all_of(replies.begin(), replies.end(), [](const Reply& r) { return !r.answer.empty(); });
}

std::vector<ControlAnswers::Answer> ControlAnswers::sent(Client client, bool json, std::uint32_t tag,
                                                         ev3proto::MsgType type, std::uint16_t agent,
                                                         const std::vector<std::uint16_t>& agents, Millis now,
                                                         Millis limit_ms) {
  Waiting w;
  w.client = client;
  w.json = json;
  w.tag = tag;
  w.type = type;
  w.all = agent == 0;
  w.until = now + limit_ms;
  for (std::uint16_t a : agents) w.replies.push_back(Reply{a, {}, {}});
  if (w.done()) return {format(w)};
  waiting_.push_back(std::move(w));
  return {};
}

std::vector<ControlAnswers::Answer> ControlAnswers::on_event(const OperatorEvent& e) {
  std::vector<Answer> out;
  const char* answer = nullptr;
  switch (e.kind) {
    case OperatorEvent::Kind::acked: answer = "acked"; break;
    case OperatorEvent::Kind::refused: answer = "refused"; break;
    case OperatorEvent::Kind::timed_out: answer = "timed_out"; break;
    case OperatorEvent::Kind::unknown_agent: answer = "unknown_agent"; break;
    case OperatorEvent::Kind::dropped: answer = "lost"; break;
    default: return out;
  }
  for (auto it = waiting_.begin(); it != waiting_.end();) {
    // An answer names its command by tag; a robot lost answers every command it still owed.
    if (e.kind != OperatorEvent::Kind::dropped && (e.tag == 0 || it->tag != e.tag)) {
      ++it;
      continue;
    }
    for (Reply& r : it->replies)
      if (r.agent == e.agent && r.answer.empty()) {
        r.answer = answer;
        if (e.kind == OperatorEvent::Kind::refused) r.reason = e.text;
      }
    if (it->done()) {
      out.push_back(format(*it));
      it = waiting_.erase(it);
    } else {
      ++it;
    }
  }
  return out;
}

std::vector<ControlAnswers::Answer> ControlAnswers::expire(Millis now) {
  std::vector<Answer> out;
  for (auto it = waiting_.begin(); it != waiting_.end();) {
    if (it->until > now) {
      ++it;
      continue;
    }
    for (Reply& r : it->replies)
      if (r.answer.empty()) r.answer = "no_answer";
    out.push_back(format(*it));
    it = waiting_.erase(it);
  }
  return out;
}

Millis ControlAnswers::deadline() const noexcept {
  Millis d = kNever;
  for (const Waiting& w : waiting_) d = std::min(d, w.until);
  return d;
}

void ControlAnswers::forget(Client c) {
  for (auto it = waiting_.begin(); it != waiting_.end();) it = it->client == c ? waiting_.erase(it) : std::next(it);
}

std::size_t ControlAnswers::waiting(Client c) const noexcept {
  return static_cast<std::size_t>(
      std::count_if(waiting_.begin(), waiting_.end(), [c](const Waiting& w) { return w.client == c; }));
}

ControlAnswers::Answer ControlAnswers::format(const Waiting& w) {
  const bool ok = std::all_of(w.replies.begin(), w.replies.end(), [](const Reply& r) { return r.answer == "acked"; });
  const std::string type(ev3proto::to_string(w.type));
  const std::string who = w.all ? "all" : std::to_string(w.replies.empty() ? 0 : w.replies[0].agent);
  std::string s;
  if (w.json) {
    s = std::string("{\"ok\":") + (ok ? "true" : "false") + ",\"command\":" + ev3proto::json_quote(type) +
        ",\"agent\":" + (w.all ? std::string("\"all\"") : who) + ",\"answers\":[";
    bool first = true;
    for (const Reply& r : w.replies) {
      if (!first) s += ',';
      first = false;
      s += "{\"agent\":" + std::to_string(r.agent) + ",\"answer\":" + ev3proto::json_quote(r.answer);
      if (r.answer == "refused") s += ",\"reason\":" + ev3proto::json_quote(r.reason);
      s += '}';
    }
    return Answer{w.client, s + "]}"};
  }
  s = std::string(ok ? "ok: " : "error: ") + who + " " + type;
  if (w.all) s += w.replies.empty() ? ": no agents" : ":";
  bool first = true;
  for (const Reply& r : w.replies) {
    s += w.all ? (first ? " " : ", ") + std::to_string(r.agent) + " " : std::string(" ");
    first = false;
    s += r.answer;
    if (r.answer == "refused") s += " (" + r.reason + ")";
  }
  return Answer{w.client, s};
}

}  // namespace ev3prog
