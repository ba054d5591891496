/// @file console.hpp
/// @brief The operator console, without I/O: parsing a command line, the fleet view (what the
///        operator sees per agent: table rows, answers to commands as text) and the status JSON. Used
///        by ev3-master and by the Master core an elected ev3-agent runs; the programs do the I/O.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include <ev3proto/master.hpp>
#include <ev3proto/rules.hpp>

namespace ev3prog {

using ev3proto::Millis;

/// One parsed console line.
struct ConsoleCommand {
  enum class Kind { none, help, list, send, wait, quit, rule } kind = Kind::none;
  std::uint16_t agent = 0;  ///< send: the agent id, 0 = all
  ev3proto::Command command;
  std::string file;         ///< send of `behaviour ID custom @FILE`: the definition's file (not read yet)
  double seconds = 0;       ///< wait
  std::string colour;       ///< rule: explore-exploit's colour ("" = switch it off)
  std::vector<std::string> rule_args;  ///< rule: key=value for BEHAVIOUR exploit
};

/// Parses one console line ("behaviour 2 wait seconds=3", "behaviour 2 custom @spiral.bhv",
/// "pause all", "rule explore-exploit red", "wait 1.5", "quit"), without reading any file.
/// Empty lines and lines starting with '#' are Kind::none. Returns "" or the error (unknown
/// command, bad agent id, bad argument).
std::string parse_console_line(std::string_view line, ConsoleCommand& out);

/// A BEHAVIOUR command made ready to send: a `custom @FILE` definition read from its file and put in
/// its compact form (the first param), and every behaviour, built-in or custom, checked as a robot of
/// model A with all its devices checks it on receipt (ev3proto/behaviour/request.hpp). Other commands
/// are left alone. Returns "" or the error, with the file and the place
/// ("spiral.bhv: line 4 col 12: unknown action 'trun' (...)").
std::string prepare_behaviour(ConsoleCommand& c);

/// parse_console_line() then prepare_behaviour(): what the programs run on an operator's line.
std::string console_command(std::string_view line, ConsoleCommand& out);

/// The console's help text.
std::string console_help();

/// What the operator sees of one agent besides the core's registry entry.
struct AgentInfo {
  std::string address;   ///< "127.0.0.1:40001"
  std::string action;    ///< Last command answer or report ("START acked", "ACTION_OK forward").
  std::string step = "-";  ///< The action id of the last ACTION_OK / ACTION_INTERR / ACTION_ERR: where
                           ///< the behaviour is ("forward"; "-" before the first).
  std::string answer = "-";  ///< The last command answer ("START acked", "BEHAVIOUR refused")
  std::string report = "-";  ///< The last report ("SENSOR_VALUE in3 COL-COLOR 5")
  Millis report_at = 0;      ///< when it came
  std::string battery = "-";  ///< From EVENT BATTERY* (else "-").
};

/// An agent that was lost (dropped from the registry).
struct LostAgent {
  std::uint16_t id = 0;
  std::string address;
  Millis at = 0;
};

/// Drop counters by reason ("decode:bad_number", "misaddressed", ...).
using Counters = std::map<std::string, std::uint64_t>;

/// The fleet as the operator sees it.
class FleetView {
 public:
  /// Text for an operator event (one line), and updates the view. @p address: the agent's address.
  std::string on_event(const ev3proto::OperatorEvent& e, const std::string& address, Millis now);

  /// The table: a header line, one line per agent (with what @p records holds of its reports), a
  /// footer with the drop counters.
  std::vector<std::string> table(const std::map<std::uint16_t, ev3proto::RegistryEntry>& reg,
                                 const Counters& drops, Millis now,
                                 const std::map<std::uint16_t, ev3proto::ReportRecord>& records = {}) const;

  /// The status JSON document; `reports` holds @p records, per agent.
  std::string status_json(const std::map<std::uint16_t, ev3proto::RegistryEntry>& reg, const Counters& drops,
                          const std::string& listening, std::uint16_t next_id, Millis now, Millis start,
                          const std::map<std::uint16_t, ev3proto::ReportRecord>& records = {}) const;

  std::map<std::uint16_t, AgentInfo>& info() { return info_; }
  const std::vector<LostAgent>& lost() const { return lost_; }
  /// The master's election role and epoch, for the status JSON (`election`; null until set: a
  /// master without `--election`).
  void set_election(std::string role, std::uint32_t epoch) {
    election_role_ = std::move(role);
    election_epoch_ = epoch;
  }

  /// `rule explore-exploit ...` (Kind::rule): switches the rule on or off; the line for the operator.
  std::string set_rule(const ConsoleCommand& c);

  /// What the rules want sent after operator event @p e (ExploreExploit: an exploring robot saw the
  /// colour): the agent, the command and a line for the operator; nothing when no rule fires.
  struct RuleCommand {
    std::uint16_t agent = 0;
    ev3proto::Command command;
    std::string say;
  };
  std::optional<RuleCommand> follow_rules(const ev3proto::OperatorEvent& e,
                                          const std::map<std::uint16_t, ev3proto::RegistryEntry>& reg);

 private:
  std::map<std::uint16_t, AgentInfo> info_;
  std::vector<LostAgent> lost_;
  std::string election_role_;  ///< empty: no election
  std::uint32_t election_epoch_ = 0;
  ev3proto::ExploreExploit explore_exploit_;
};

/// A record of reports in a few words: "1-57 (2 dropped, gap 58-60)", "-" when it is empty.
std::string report_summary(const ev3proto::ReportRecord& r);
/// The same as a JSON object: first, last, recorded, dropped, skipped, gap ([from, to] or null).
std::string report_json(const ev3proto::ReportRecord& r);

/// The state column of an entry: SYNCING until it ACKs MASTER, then the state of its last PING
/// (SYNCED before the first one).
std::string state_text(const ev3proto::RegistryEntry& e);

}  // namespace ev3prog
