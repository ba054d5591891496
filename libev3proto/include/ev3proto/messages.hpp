/// @file messages.hpp
/// @brief The message types of wire format v2 as a constexpr table (a copy of docs/messages.tsv).
///
/// One row per type. New types add rows to
/// kMessageTable and enumerators to MsgType; nothing else needs to change. A unit test compares this
/// table with docs/messages.tsv row by row.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string_view>

namespace ev3proto {

/// Largest number of params any datagram may carry (docs/protocol.md).
inline constexpr std::size_t kMaxParams = 32;

/// The message types defined by wire format v2 (the numeric value is the wire `type` field).
enum class MsgType : std::uint8_t {
  AGENT = 1,          ///< agent -> 0: an agent announces itself: its model, then the model's devices.
  MASTER = 2,         ///< master -> agent: assigns an id (receiver field) to an announced temporary id.
  ACK = 3,            ///< both: acknowledges a msgid.
  NOT = 4,            ///< agent -> master: refuses a msgid, with a reason.
  PING = 5,           ///< agent -> master: heartbeat carrying the agent's state.
  PONG = 6,           ///< master -> agent: answers a PING.
  BEHAVIOUR = 7,      ///< master -> agent: behaviour name and its arguments.
  START = 8,          ///< master -> agent: start the behaviour.
  STOP = 9,           ///< master -> agent: stop.
  PAUSE = 10,         ///< master -> agent: pause.
  RESUME = 11,        ///< master -> agent: resume after PAUSE.
  STANDBY = 12,       ///< master -> agent: stand by.
  CONTINUE = 13,      ///< master -> agent: continue after STANDBY.
  RESTART = 14,       ///< master -> agent: restart.
  ACTION_OK = 15,     ///< agent -> master: an action finished.
  ACTION_INTERR = 16, ///< agent -> master: an action was interrupted by an event.
  ACTION_ERR = 17,    ///< agent -> master: an action failed.
  SENSOR_VALUE = 18,  ///< agent -> master: port, mode and one or more values.
  PANIC = 19,         ///< agent -> 0: the agent lost its master.
  EVENT = 20,         ///< agent -> master: an event and its details.
  RELAY_REQ = 21,     ///< agent -> 0: an agent without master asks for a relay.
  RELAY_OFFER = 22,   ///< agent -> agent: a directly linked peer offers to relay.
  RELAY_ACCEPT = 23,  ///< agent -> agent: the agent takes the offer.
  RELAY_ROUTE = 24,   ///< agent -> master: the relay tells the master the route.
  RELAY = 25,         ///< both: an inner datagram forwarded one hop.
  RELAY_DROP = 26,    ///< agent -> agent: the relay lost its master link.
  ELECT = 27,         ///< agent -> 0: a candidate stands in an epoch.
  VOTE = 28,          ///< agent -> agent: a vote for a candidate in an epoch.
  LEADER = 29,        ///< master -> 0: the master of an epoch and the fleet membership.
  EPOCH_STALE = 30,   ///< both: the receiver is behind; the epoch seen.
  EPOCH_CMD = 31,     ///< master -> agent: a command fenced by the master's epoch.
  HANDOVER = 32,      ///< master -> master: the registry handed to the new master.
  PREVOTE_OK = 33,    ///< agent -> agent: no master here; would vote for the RELAY_REQ's sender.
  REPORT = 40,        ///< agent -> master: report number seq (a report datagram inside), the lowest held.
  REPORT_DROPPED = 41, ///< agent -> master: reports first..last were dropped by the agent's bound.
  REPORT_ACK = 42,    ///< master -> agent: every report up to this number is in the master's record.
};

/// Kind of a param value (column `params` of docs/messages.tsv).
enum class ParamKind : std::uint8_t {
  text,  ///< any byte string.
  u16,   ///< canonical decimal number 0..65535.
  u32,   ///< canonical decimal number 0..4294967295.
  state, ///< one of IDLE, ACTIVE, WORKING, PAUSED, PANIC.
};

/// Who sends a message type (column `direction` of docs/messages.tsv).
enum class Direction : std::uint8_t {
  agent_to_broadcast, ///< "agent->0"
  master_to_agent,    ///< "master->agent"
  agent_to_master,    ///< "agent->master"
  both,               ///< "both"
  agent_to_agent,     ///< "agent->agent"
  master_to_broadcast, ///< "master->0"
  master_to_master,   ///< "master->master"
};

/// The states an agent reports in PING (ParamKind::state).
enum class AgentState : std::uint8_t { IDLE, ACTIVE, WORKING, PAUSED, PANIC };

/// One declared param of a message type: its kind and its name in the table.
struct ParamSpec {
  ParamKind kind;        ///< Kind of the value.
  std::string_view name; ///< Name as written in docs/messages.tsv (without `...`).
};

/// Most params any row declares by name (the rest repeat the last one).
inline constexpr std::size_t kMaxDeclaredParams = 4;

/// One row of the message table.
struct MessageSpec {
  std::uint8_t type;      ///< Wire type number 1..255.
  std::string_view name;  ///< Upper-case name, e.g. "PING".
  Direction direction;    ///< Who sends it.
  std::uint8_t min_params; ///< Fewest params accepted.
  std::uint8_t max_params; ///< Most params accepted (<= kMaxParams).
  std::uint8_t declared;  ///< Number of entries of `params` in use.
  bool last_repeats;      ///< The last declared param repeats up to max_params (`...` in the table).
  std::array<ParamSpec, kMaxDeclaredParams> params; ///< Declared params, in order.

  /// Kind of param @p i (0-based); text for an index beyond what the row declares.
  constexpr ParamKind kind(std::size_t i) const noexcept {
    if (i < declared) return params[i].kind;
    if (last_repeats && declared > 0) return params[declared - 1u].kind;
    return ParamKind::text;
  }
};

namespace detail {
/// Shorthand constructors for the table below.
constexpr ParamSpec P(ParamKind k, std::string_view n) noexcept { return ParamSpec{k, n}; }
inline constexpr ParamSpec kNoParam{ParamKind::text, {}};
} // namespace detail

/// The message table of wire format v2, in type order (docs/messages.tsv).
inline constexpr MessageSpec kMessageTable[] = {
    // type name direction min max declared repeats params
    {1, "AGENT", Direction::agent_to_broadcast, 1, 32, 2, true,
     {detail::P(ParamKind::text, "model"), detail::P(ParamKind::text, "device"), detail::kNoParam, detail::kNoParam}},
    {2, "MASTER", Direction::master_to_agent, 1, 1, 1, false,
     {detail::P(ParamKind::u16, "announced_id"), detail::kNoParam, detail::kNoParam, detail::kNoParam}},
    {3, "ACK", Direction::both, 1, 1, 1, false,
     {detail::P(ParamKind::u32, "acked_msgid"), detail::kNoParam, detail::kNoParam, detail::kNoParam}},
    {4, "NOT", Direction::agent_to_master, 2, 2, 2, false,
     {detail::P(ParamKind::u32, "refused_msgid"), detail::P(ParamKind::text, "reason"), detail::kNoParam,
      detail::kNoParam}},
    {5, "PING", Direction::agent_to_master, 1, 1, 1, false,
     {detail::P(ParamKind::state, "state"), detail::kNoParam, detail::kNoParam, detail::kNoParam}},
    {6, "PONG", Direction::master_to_agent, 1, 1, 1, false,
     {detail::P(ParamKind::u32, "ping_msgid"), detail::kNoParam, detail::kNoParam, detail::kNoParam}},
    {7, "BEHAVIOUR", Direction::master_to_agent, 1, 32, 2, true,
     {detail::P(ParamKind::text, "name"), detail::P(ParamKind::text, "argument"), detail::kNoParam,
      detail::kNoParam}},
    {8, "START", Direction::master_to_agent, 0, 0, 0, false, {}},
    {9, "STOP", Direction::master_to_agent, 0, 0, 0, false, {}},
    {10, "PAUSE", Direction::master_to_agent, 0, 0, 0, false, {}},
    {11, "RESUME", Direction::master_to_agent, 0, 0, 0, false, {}},
    {12, "STANDBY", Direction::master_to_agent, 0, 0, 0, false, {}},
    {13, "CONTINUE", Direction::master_to_agent, 0, 0, 0, false, {}},
    {14, "RESTART", Direction::master_to_agent, 0, 0, 0, false, {}},
    {15, "ACTION_OK", Direction::agent_to_master, 1, 1, 1, false,
     {detail::P(ParamKind::u32, "action"), detail::kNoParam, detail::kNoParam, detail::kNoParam}},
    {16, "ACTION_INTERR", Direction::agent_to_master, 2, 2, 2, false,
     {detail::P(ParamKind::u32, "action"), detail::P(ParamKind::text, "event"), detail::kNoParam,
      detail::kNoParam}},
    {17, "ACTION_ERR", Direction::agent_to_master, 2, 2, 2, false,
     {detail::P(ParamKind::u32, "action"), detail::P(ParamKind::text, "error"), detail::kNoParam,
      detail::kNoParam}},
    {18, "SENSOR_VALUE", Direction::agent_to_master, 3, 32, 3, true,
     {detail::P(ParamKind::text, "port"), detail::P(ParamKind::text, "mode"),
      detail::P(ParamKind::text, "value"), detail::kNoParam}},
    {19, "PANIC", Direction::agent_to_broadcast, 0, 0, 0, false, {}},
    {20, "EVENT", Direction::agent_to_master, 1, 32, 2, true,
     {detail::P(ParamKind::text, "event"), detail::P(ParamKind::text, "detail"), detail::kNoParam,
      detail::kNoParam}},
    {21, "RELAY_REQ", Direction::agent_to_broadcast, 1, 3, 3, false,
     {detail::P(ParamKind::u32, "epoch"), detail::P(ParamKind::u32, "score"), detail::P(ParamKind::u32, "members_epoch"), detail::kNoParam}},
    {22, "RELAY_OFFER", Direction::agent_to_agent, 2, 2, 2, false,
     {detail::P(ParamKind::u32, "epoch"), detail::P(ParamKind::u16, "master"), detail::kNoParam, detail::kNoParam}},
    {23, "RELAY_ACCEPT", Direction::agent_to_agent, 2, 2, 2, false,
     {detail::P(ParamKind::u32, "epoch"), detail::P(ParamKind::u16, "master"), detail::kNoParam, detail::kNoParam}},
    {24, "RELAY_ROUTE", Direction::agent_to_master, 2, 2, 2, false,
     {detail::P(ParamKind::u32, "epoch"), detail::P(ParamKind::u16, "relayed"), detail::kNoParam, detail::kNoParam}},
    {25, "RELAY", Direction::both, 2, 2, 2, false,
     {detail::P(ParamKind::u16, "target"), detail::P(ParamKind::text, "datagram"), detail::kNoParam, detail::kNoParam}},
    {26, "RELAY_DROP", Direction::agent_to_agent, 1, 1, 1, false,
     {detail::P(ParamKind::u32, "epoch"), detail::kNoParam, detail::kNoParam, detail::kNoParam}},
    {27, "ELECT", Direction::agent_to_broadcast, 3, 3, 3, false,
     {detail::P(ParamKind::u32, "epoch"), detail::P(ParamKind::u32, "score"), detail::P(ParamKind::u32, "members_epoch"), detail::kNoParam}},
    {28, "VOTE", Direction::agent_to_agent, 2, 2, 2, false,
     {detail::P(ParamKind::u32, "epoch"), detail::P(ParamKind::u16, "candidate"), detail::kNoParam, detail::kNoParam}},
    {29, "LEADER", Direction::master_to_broadcast, 2, 32, 3, true,
     {detail::P(ParamKind::u32, "epoch"), detail::P(ParamKind::u16, "leader"), detail::P(ParamKind::u16, "member"), detail::kNoParam}},
    {30, "EPOCH_STALE", Direction::both, 1, 1, 1, false,
     {detail::P(ParamKind::u32, "epoch"), detail::kNoParam, detail::kNoParam, detail::kNoParam}},
    {31, "EPOCH_CMD", Direction::master_to_agent, 2, 2, 2, false,
     {detail::P(ParamKind::u32, "epoch"), detail::P(ParamKind::text, "datagram"), detail::kNoParam, detail::kNoParam}},
    {32, "HANDOVER", Direction::master_to_master, 2, 32, 2, true,
     {detail::P(ParamKind::u32, "epoch"), detail::P(ParamKind::text, "registry"), detail::kNoParam, detail::kNoParam}},
    {33, "PREVOTE_OK", Direction::agent_to_agent, 1, 1, 1, false,
     {detail::P(ParamKind::u32, "epoch"), detail::kNoParam, detail::kNoParam, detail::kNoParam}},
    {40, "REPORT", Direction::agent_to_master, 3, 3, 3, false,
     {detail::P(ParamKind::u32, "seq"), detail::P(ParamKind::u32, "first"), detail::P(ParamKind::text, "datagram"),
      detail::kNoParam}},
    {41, "REPORT_DROPPED", Direction::agent_to_master, 2, 2, 2, false,
     {detail::P(ParamKind::u32, "first"), detail::P(ParamKind::u32, "last"), detail::kNoParam, detail::kNoParam}},
    {42, "REPORT_ACK", Direction::master_to_agent, 1, 1, 1, false,
     {detail::P(ParamKind::u32, "stored"), detail::kNoParam, detail::kNoParam, detail::kNoParam}},
};

/// Number of rows of kMessageTable.
inline constexpr std::size_t kMessageTableSize = sizeof(kMessageTable) / sizeof(kMessageTable[0]);

namespace detail {
/// Marks a type number the table does not define in kTypeIndex.
inline constexpr std::uint8_t kNoRow = 0xFF;
static_assert(kMessageTableSize < kNoRow, "table too large for the 8-bit type index");

/// Builds the type number -> row index map at compile time.
constexpr std::array<std::uint8_t, 256> make_type_index() noexcept {
  std::array<std::uint8_t, 256> idx{};
  for (auto& e : idx) e = kNoRow;
  for (std::size_t r = 0; r < kMessageTableSize; ++r) idx[kMessageTable[r].type] = static_cast<std::uint8_t>(r);
  return idx;
}
/// Type number -> index into kMessageTable, or kNoRow.
inline constexpr std::array<std::uint8_t, 256> kTypeIndex = make_type_index();

/// Checks the table's invariants at compile time.
constexpr bool table_is_sane() noexcept {
  for (std::size_t r = 0; r < kMessageTableSize; ++r) {
    const MessageSpec& s = kMessageTable[r];
    if (s.type == 0 || s.min_params > s.max_params || s.max_params > kMaxParams) return false;
    if (s.declared > kMaxDeclaredParams) return false;
    if (r > 0 && kMessageTable[r - 1].type >= s.type) return false; // sorted, no duplicates
  }
  return true;
}
static_assert(table_is_sane(), "kMessageTable breaks an invariant (type 0, min>max, max>32, order)");
} // namespace detail

/// The row for wire type number @p type, or nullptr if the table does not define it.
constexpr const MessageSpec* find_spec(std::uint8_t type) noexcept {
  const std::uint8_t r = detail::kTypeIndex[type];
  return r == detail::kNoRow ? nullptr : &kMessageTable[r];
}

/// The row for @p type, or nullptr if the table does not define it.
constexpr const MessageSpec* find_spec(MsgType type) noexcept {
  return find_spec(static_cast<std::uint8_t>(type));
}

/// Name of a message type as in the table ("PING"), or "" if the table does not define it.
constexpr std::string_view to_string(MsgType type) noexcept {
  const MessageSpec* s = find_spec(type);
  return s ? s->name : std::string_view{};
}

/// Spelling of a direction as in docs/messages.tsv ("agent->master").
constexpr std::string_view to_string(Direction d) noexcept {
  switch (d) {
    case Direction::agent_to_broadcast: return "agent->0";
    case Direction::master_to_agent: return "master->agent";
    case Direction::agent_to_master: return "agent->master";
    case Direction::both: return "both";
    case Direction::agent_to_agent: return "agent->agent";
    case Direction::master_to_broadcast: return "master->0";
    case Direction::master_to_master: return "master->master";
  }
  return {};
}

/// Spelling of a param kind as in docs/messages.tsv ("u32").
constexpr std::string_view to_string(ParamKind k) noexcept {
  switch (k) {
    case ParamKind::text: return "text";
    case ParamKind::u16: return "u16";
    case ParamKind::u32: return "u32";
    case ParamKind::state: return "state";
  }
  return {};
}

/// Spelling of an agent state on the wire ("WORKING").
constexpr std::string_view to_string(AgentState s) noexcept {
  switch (s) {
    case AgentState::IDLE: return "IDLE";
    case AgentState::ACTIVE: return "ACTIVE";
    case AgentState::WORKING: return "WORKING";
    case AgentState::PAUSED: return "PAUSED";
    case AgentState::PANIC: return "PANIC";
  }
  return {};
}

/// Parses a state's wire spelling; returns false (and leaves @p out alone) if it is not one.
inline bool parse_state(std::string_view s, AgentState& out) noexcept {
  // Unrolled, each comparison is with a name of known length, which compilers do without a call.
#pragma GCC unroll 5
  for (const AgentState a : {AgentState::IDLE, AgentState::ACTIVE, AgentState::WORKING, AgentState::PAUSED,
                             AgentState::PANIC}) {
    if (s == to_string(a)) {
      out = a;
      return true;
    }
  }
  return false;
}

} // namespace ev3proto
