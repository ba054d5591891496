/// @file console.hpp
/// @brief The operator console, without I/O: parsing a command line, the fleet view (what the
///        operator sees per agent: table rows, answers to commands as text) and the status JSON. Used
///        by ev3-master and by the Master core an elected ev3-agent runs; the programs do the I/O.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include <ev3proto/master.hpp>

namespace ev3prog {

using ev3proto::Millis;

/// One parsed console line.
struct ConsoleCommand {
  enum class Kind { none, help, list, send, wait, quit } kind = Kind::none;
  std::uint16_t agent = 0;  ///< send: the agent id, 0 = all
  ev3proto::Command command;
  double seconds = 0;       ///< wait
};

/// Parses one console line ("behaviour 2 wait seconds=3", "pause all", "wait 1.5", "quit").
/// Empty lines and lines starting with '#' are Kind::none. Returns "" or the error (unknown
/// command, bad agent id, bad argument).
std::string parse_console_line(std::string_view line, ConsoleCommand& out);

/// The console's help text.
std::string console_help();

/// What the operator sees of one agent besides the core's registry entry.
struct AgentInfo {
  std::string address;   ///< "127.0.0.1:40001"
  std::string action;    ///< Last command answer or report ("START acked", "ACTION_OK 0").
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

  /// The table: a header line, one line per agent, a footer with the drop counters.
  std::vector<std::string> table(const std::map<std::uint16_t, ev3proto::RegistryEntry>& reg,
                                 const Counters& drops, Millis now) const;

  /// The status JSON document.
  std::string status_json(const std::map<std::uint16_t, ev3proto::RegistryEntry>& reg, const Counters& drops,
                          const std::string& listening, std::uint16_t next_id, Millis now, Millis start) const;

  std::map<std::uint16_t, AgentInfo>& info() { return info_; }
  const std::vector<LostAgent>& lost() const { return lost_; }

 private:
  std::map<std::uint16_t, AgentInfo> info_;
  std::vector<LostAgent> lost_;
};

/// The state column of an entry: SYNCING until it ACKs MASTER, then the state of its last PING
/// (SYNCED before the first one).
std::string state_text(const ev3proto::RegistryEntry& e);

}  // namespace ev3prog
