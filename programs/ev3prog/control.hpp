/// @file control.hpp
/// @brief The control socket's answers, without I/O: ev3-master's `--control` socket takes the
///        console language, one command per line, and gives one answer per line (docs/programs.md,
///        "The control socket"). A command to robots is answered once each robot has answered it
///        (acked, refused, or no answer after the resends); what the master answers at once (list,
///        help, rule, an error) is formatted here too. The program does the socket I/O.
#pragma once

#include <cstdint>
#include <deque>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <ev3proto/master.hpp>

namespace ev3prog {

using ev3proto::Millis;

/// A line from a control client: `--json` as its first word asks for a JSON answer.
struct ControlLine {
  bool json = false;
  std::string command;  ///< the console line, `--json` taken off
};
/// Splits @p line (no newline) into its JSON flag and its console command; @p json_default is the
/// master's `--json`.
ControlLine parse_control_line(std::string_view line, bool json_default);

/// An answer given at once: @p text (`ok` when empty), as text or as {"ok":true,"answer":...}.
std::string control_ok(bool json, const std::string& text);
/// An error answer: "error: TEXT" or {"ok":false,"error":TEXT}.
std::string control_error(bool json, const std::string& text);
/// The answer to `list`: the table's lines joined by " | " (text), or {"ok":true,"status":STATUS}
/// with the master's status JSON (the document `--status-json` writes).
std::string control_list(bool json, const std::vector<std::string>& table, const std::string& status_json);

/// The control clients' commands to robots that wait for their answers. Each carries a tag
/// (Command::tag) that the master core gives back in the OperatorEvent of each robot's answer, so
/// an answer is never taken for another command's: not the console's, nor one the core made itself
/// (reconcile's).
class ControlAnswers {
 public:
  using Client = std::uint32_t;  ///< a control connection
  struct Answer {
    Client client = 0;
    std::string line;  ///< the whole answer, no newline
  };

  /// Command @p tag of type @p type sent at @p now for @p client (who asked in JSON or not) to agent
  /// @p agent, or with @p agent 0 to all: @p agents, the ids the core queued it for (none: answered
  /// at once, returned). An agent that has not answered within @p limit_ms is reported as giving
  /// no answer.
  std::vector<Answer> sent(Client client, bool json, std::uint32_t tag, ev3proto::MsgType type, std::uint16_t agent,
                           const std::vector<std::uint16_t>& agents, Millis now, Millis limit_ms);
  /// An operator event: the answers it completes (a command's last robot answered). A robot
  /// dropped from the registry (lost) answers what it still owed as `lost`.
  std::vector<Answer> on_event(const ev3proto::OperatorEvent& e);
  /// The answers of the commands whose time ran out by @p now.
  std::vector<Answer> expire(Millis now);
  /// When expire() next has something to do (kNever: nothing is waiting).
  Millis deadline() const noexcept;
  /// Client @p c is gone: its commands wait no more for answers nobody reads.
  void forget(Client c);
  /// Commands of client @p c waiting for an answer.
  std::size_t waiting(Client c) const noexcept;

  static constexpr Millis kNever = ~Millis{0};

 private:
  struct Reply {
    std::uint16_t agent = 0;
    std::string answer;  ///< "" while waiting, else "acked", "refused", "timed_out", "unknown_agent", "lost", "no_answer"
    std::string reason;  ///< a refusal's reason
  };
  struct Waiting {
    Client client = 0;
    bool json = false;
    std::uint32_t tag = 0;
    ev3proto::MsgType type = ev3proto::MsgType::START;
    bool all = false;
    Millis until = 0;
    std::vector<Reply> replies;
    bool done() const;
  };
  static Answer format(const Waiting& w);
  std::deque<Waiting> waiting_;
};

}  // namespace ev3prog
