// Drives one Master from transcript commands (tests/cpp/testdata/master_*.txt).
//
// Inputs:
//   master [resend=ms] [drop=ms] [max_resends=n] [next_id=n] [next_msgid=n] [at=ms]
//   advance MS
//   recv DATAGRAM [from=PEER]            (symbolic or wire bytes, as agent_driver.hpp; peer 100)
//   cmd assign ID|all NAME [ARG...]      BEHAVIOUR
//   cmd start|stop|pause|resume|standby|continue|restart ID|all
//   show                                 election role, epoch, members, registry
//   trace                                print the NDJSON trace lines of this case
// Outputs: each spec action by name (a MasterTick only when it did something), followed,
// indented, by what it did: `send peer=P DATAGRAM` / `send broadcast DATAGRAM` (symbolic) and
// `op KIND agent=ID ...` (operator events); a datagram no action took: `ignored`. Last:
// `deadline T`.
#pragma once

#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "fixed_timers.hpp"
#include "ev3proto/master.hpp"
#include "ev3proto/trace.hpp"
#include "symbolic.hpp"

namespace ev3test {

using namespace ev3proto;

class MasterDriver;

/// Trace sink: each action's name followed by what it sent and reported (the driver drains the
/// master's queues at every record), and the NDJSON lines.
struct MasterLog {
  static constexpr bool enabled = true;
  MasterDriver* driver = nullptr;
  std::vector<std::string> json;
  void record(const MasterTraceRecord& r);
};

using TracedMaster = Master<MasterLog>;

inline bool command_type(const std::string& w, MsgType& t) {
  static const std::pair<const char*, MsgType> kCmds[] = {
      {"assign", MsgType::BEHAVIOUR}, {"start", MsgType::START},     {"stop", MsgType::STOP},
      {"pause", MsgType::PAUSE},      {"resume", MsgType::RESUME},   {"standby", MsgType::STANDBY},
      {"continue", MsgType::CONTINUE}, {"restart", MsgType::RESTART}};
  for (const auto& c : kCmds)
    if (w == c.first) {
      t = c.second;
      return true;
    }
  return false;
}

/// Prints an operator event as a transcript line.
inline std::string op_line(const OperatorEvent& e) {
  std::string l = "op " + std::string(to_string(e.kind)) + " agent=" + std::to_string(e.agent);
  if (e.kind != OperatorEvent::Kind::dropped && e.kind != OperatorEvent::Kind::state)
    l += " " + std::string(to_string(e.command));
  if (!e.text.empty()) l += " " + e.text;
  if (e.recorded()) l += " n=" + std::to_string(e.seq) + (e.last ? "-" + std::to_string(e.last) : "");
  return l;
}

class MasterDriver {
 public:
  std::vector<std::string> run(const std::vector<std::string>& input) {
    lines_.clear();
    log_.json.clear();
    log_.driver = this;
    std::vector<std::string> errors;
    bool show_trace = false;
    for (const std::string& line : input) {
      std::istringstream in(line);
      std::vector<std::string> w;
      for (std::string s; in >> s;) w.push_back(s);
      if (w.empty()) continue;
      if (w[0] == "master") {
        MasterConfig c;
        c.timers = ev3test::fixed_timers();
        for (std::size_t i = 1; i < w.size(); ++i) {
          const auto eq = w[i].find('=');
          const std::string k = w[i].substr(0, eq), v = w[i].substr(eq + 1);
          if (k == "resend") c.timers.set(Timer::resend, std::stoull(v));
          else if (k == "drop") c.timers.set(Timer::drop, std::stoull(v));
          else if (k == "max_resends") c.max_resends = static_cast<std::uint32_t>(std::stoul(v));
          else if (k == "next_id") c.next_id = static_cast<std::uint16_t>(std::stoul(v));
          else if (k == "next_msgid") c.next_msgid = static_cast<std::uint32_t>(std::stoul(v));
          else if (k == "at") now_ = std::stoull(v);
          else if (k == "election") c.election = v == "1";
          else if (k == "epoch") c.epoch = static_cast<std::uint32_t>(std::stoul(v));
          else if (k == "members_epoch") c.members_epoch = static_cast<std::uint32_t>(std::stoul(v));
          else if (k == "self") c.self_id = static_cast<std::uint16_t>(std::stoul(v));
          else if (k == "candidate") c.candidate = v == "1";
          else if (k == "heartbeat") c.timers.set(Timer::leader_heartbeat, std::stoull(v));
          else if (k == "candidate_timeout") c.timers.set(Timer::candidate, std::stoull(v));
          else if (k == "members") {
            std::istringstream ms(v);
            for (std::string id; std::getline(ms, id, ',');) c.members.push_back(static_cast<std::uint16_t>(std::stoul(id)));
          }
          else errors.push_back("error: bad master option " + w[i]);
        }
        master_ = std::make_unique<TracedMaster>(c, now_, &log_);
      } else if (!master_) {
        errors.push_back("error: no master");
      } else if (w[0] == "advance" && w.size() == 2) {
        now_ += std::stoull(w[1]);
        master_->advance(now_);
      } else if (w[0] == "recv" && w.size() >= 2) {
        // The datagram is the rest of the line (params may hold spaces), minus a final from=PEER.
        Peer from = 100;
        std::string d = line.substr(line.find(' ') + 1);
        const auto f = d.rfind(" from=");
        if (f != std::string::npos) {
          from = static_cast<Peer>(std::stoul(d.substr(f + 6)));
          d = d.substr(0, f);
        }
        std::string error;
        if (is_symbolic(d) && !parse_symbolic(d, d, error)) {
          errors.push_back("error: " + error);
          continue;
        }
        master_->advance(now_);
        if (!master_->handle_datagram(d, from, now_).taken()) lines_.push_back("ignored");
      } else if (w[0] == "cmd" && w.size() >= 3) {
        MsgType t;
        if (!command_type(w[1], t)) {
          errors.push_back("error: bad command " + w[1]);
          continue;
        }
        Command c = Command::simple(t);
        if (t == MsgType::BEHAVIOUR && w.size() >= 4) c = Command::assign(w[3], {w.begin() + 4, w.end()});
        const std::uint16_t id = w[2] == "all" ? 0 : static_cast<std::uint16_t>(std::stoul(w[2]));
        master_->command(id, c, now_);
      } else if (w[0] == "trace") {
        show_trace = true;
      } else if (w[0] == "show") {
        std::string l = "show life=" + std::string(to_string(master_->role())) + " epoch=" +
                        std::to_string(master_->epoch()) + " members=";
        for (auto id : master_->want()) l += std::to_string(id) + ",";
        l += " published=";
        for (auto id : master_->members()) l += std::to_string(id) + ",";
        l += "@" + std::to_string(master_->members_epoch());
        l += " reg=";
        for (const auto& kv : master_->registry())
          l += std::to_string(kv.first) + (kv.second.via ? "via" + std::to_string(kv.second.via) : "") + ",";
        lines_.push_back(l + " handed_over=" + (master_->handed_over() ? "1" : "0"));
      } else {
        errors.push_back("error: bad input: " + line);
      }
    }
    std::vector<std::string> lines = std::move(lines_);
    lines_.clear();
    if (show_trace)
      for (const auto& j : log_.json) lines.push_back("trace " + j);
    const Millis d = master_ ? master_->next_deadline() : TracedMaster::kNever;
    lines.push_back(d == TracedMaster::kNever ? "deadline none" : "deadline " + std::to_string(d));
    for (auto& x : errors) lines.push_back(x);
    return lines;
  }

  /// Called by the trace sink after each action: its name, then what it queued.
  void on_record(const MasterTraceRecord& r) {
    std::vector<std::string> out;
    MasterTransmit t;
    while (master_ && master_->poll_transmit(t))
      out.push_back(t.dest == Dest::broadcast ? "  send broadcast " + symbolic(t.bytes)
                                              : "  send peer=" + std::to_string(t.peer) + " " + symbolic(t.bytes));
    OperatorEvent e;
    while (master_ && master_->poll_event(e)) out.push_back("  " + op_line(e));
    if (r.action == Action::MasterTick && out.empty()) return;
    lines_.push_back(std::string(to_string(r.action)));
    for (auto& l : out) lines_.push_back(std::move(l));
  }

 private:
  MasterLog log_;
  std::vector<std::string> lines_;
  std::unique_ptr<TracedMaster> master_;
  Millis now_ = 0;
};

inline void MasterLog::record(const MasterTraceRecord& r) {
  json.push_back(to_ndjson(r));
  if (driver != nullptr) driver->on_record(r);
}

}  // namespace ev3test
