/// @file program.hpp
/// @brief What ev3-agent and ev3-master do alike around their cores, written once: main()
///        (`--driver` anywhere on the command line selects the driver mode, docs/driver.md;
///        otherwise the options are parsed: usage on --help, a clear error and exit status 2 on a bad
///        flag), the driver mode's main, the program shell (Shell: log, trace file, socket, loop,
///        script, drop counters, state file), an agent's address for the operator.
#pragma once

#include <poll.h>

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include <ev3proto/master.hpp>

#include "ev3io/cli.hpp"
#include "ev3io/log.hpp"
#include "ev3io/loop.hpp"
#include "ev3io/udp.hpp"
#include "ev3prog/console.hpp"
#include "ev3prog/driver_json.hpp"
#include "ev3prog/script.hpp"
#include "ev3prog/trace_file.hpp"

namespace ev3prog {

/// A program's main(): @p name ("ev3-agent") for the messages; @p run_driver the driver mode;
/// @p parse the options parser; then a @p Program (constructed from the options, kept in a static:
/// the cores are large) runs: its run() gives the exit status.
template <typename Program, typename Options>
int program_main(int argc, char** argv, const char* name, int (*run_driver)(int, char**),
                 ev3io::ParseOutcome (*parse)(int, const char* const*, Options&, std::string&)) {
  for (int i = 1; i < argc; ++i)
    if (std::strcmp(argv[i], "--driver") == 0) return run_driver(argc, argv);
  static Options o;
  std::string msg;
  switch (parse(argc, argv, o, msg)) {
    case ev3io::ParseOutcome::help: std::printf("%s", msg.c_str()); return 0;
    case ev3io::ParseOutcome::error:
      std::fprintf(stderr, "%s: %s (try --help)\n", name, msg.c_str());
      return 2;
    case ev3io::ParseOutcome::run: break;
  }
  static Program p(o);
  return p.run();
}

/// The driver mode's main (`PROGRAM --driver [--trace FILE]`, docs/driver.md): reads the options
/// (driver_options()), then runs a @p Driver (constructed from the trace file, kept in a static: the
/// cores are large) until stdin ends.
template <typename Driver>
int driver_main(int argc, char** argv, const char* program, const char* core, const char* inputs) {
  std::FILE* trace = nullptr;
  const int rc = driver_options(argc, argv, program, core, inputs, trace);
  if (rc >= 0) return rc;
  static Driver d(trace);
  const int status = d.run();
  if (trace != nullptr) std::fclose(trace);
  return status;
}

/// The program shell: what ev3-agent and ev3-master hold around their cores and do with it alike,
/// written once. The log and the --trace file, the UDP socket and its bounded read, the signals that
/// stop the loop and the loop's sleep, the console script, the drop counters, the state file (read,
/// and written atomically: the caller's parser from ev3proto/durable.hpp checks its text) and the
/// last lines at exit. Each program's Program owns one and adds only what is its own (the robot and
/// its devices; the terminal, the console's stdin and the status JSON).
class Shell {
 public:
  /// Datagrams read in one turn of the loop: a flood delays what the loop owes (answers, resends,
  /// copies, deadlines, the status) by at most one batch.
  static constexpr std::size_t kBatch = 64;

  /// The shell of program @p program ("ev3-agent": the prefix of its messages on stderr), its socket
  /// injecting @p faults.
  Shell(const char* program, const ev3io::FaultConfig& faults) : net(faults), program_(program) {}

  /// Opens the log (named @p log_name, at --log-level, into --log-file or stderr) and the --trace
  /// file, reads --key-file (signed mode: from then on every copy sent is signed and only datagrams
  /// signed with that key reach the program; the others are counted as drops "auth:<reason>"),
  /// then binds the socket. 0 when all are open; otherwise the exit status after saying on stderr
  /// what failed: 2 for an option's bad value, 1 when the socket cannot be bound.
  int open(const char* log_name, const ev3io::CommonOptions& o);

  /// Loads the console script @p path (given with @p flag, "--script"); nothing when @p path is
  /// empty. False after saying on stderr why it cannot be read.
  bool load_script(const char* flag, const std::string& path);

  /// Reads the state file @p path (given with @p flag) into @p text: true, with no @p text when
  /// there is none yet (a first start); false after saying on stderr why it cannot be read.
  bool read_state(const char* flag, const std::string& path, std::optional<std::string>& text);
  /// Says on stderr that the state file @p path (given with @p flag) is damaged, @p why; false.
  bool damaged(const char* flag, const std::string& path, std::string_view why);
  /// Flushes the trace file, then writes @p text to the state file @p path atomically
  /// (ev3io::write_state_file; nothing when @p path is "": true). False after
  /// saying in the log and on stderr that @p what is not on disk and that the program sends nothing
  /// more ("ev3-agent: reason; the election state is not on disk: sending nothing more, exiting").
  bool save_state(const char* what, const std::string& path, std::string_view text);

  /// The loop goes on: no signal asked to stop, and every state write succeeded.
  bool running() const noexcept { return signals.stop_signal() == 0 && !state_failed; }

  /// Reads up to kBatch datagrams, each to @p on(bytes, from, now). True when it stopped at the
  /// bound: the socket may hold more, and the loop must not sleep before reading on.
  template <typename On>
  bool receive(On&& on) {
    for (std::size_t n = 0; n < kBatch; ++n) {
      if (!net.receive(bytes_, from_)) return false;
      if (opener_ != nullptr && !authentic()) continue;
      on(bytes_, from_, ev3io::monotonic_ms());
    }
    return true;
  }

  /// Counts datagram @p bytes from @p from (none: not said) dropped for @p why; a verbose log line
  /// names it (the address is formatted only then).
  void drop(const std::string& why, std::string_view bytes, const ev3io::Endpoint* from = nullptr);
  /// Counts @p why without a log line.
  void count(const std::string& why) { ++drops[why]; }
  /// The drop counters as one line: "decode:bad_number=12 misaddressed=3", "none" when empty.
  std::string drops_line() const;

  /// Sleeps until @p deadline (the program's own), the socket's next copy due, the log's and the
  /// trace file's next flush, a datagram, a signal, or one of @p extra's @p n_extra descriptors
  /// (their revents set; at most kMaxExtra, checked where it is called); not at all when @p more
  /// (receive() stopped at its bound). Returns poll's count.
  static constexpr std::size_t kMaxExtra = 10;  // stdin, a control socket and its 8 connections
  int wait(Millis now, Millis deadline, bool more, pollfd* extra = nullptr, std::size_t n_extra = 0);

  /// The stop line: why (the state file, @p why when given, else the signal) and the drop
  /// counters: "stopping (signal 15); drops: decode:bad_number=12". The copies still due go out first.
  void log_stop(const char* why = nullptr);
  /// The last step: the log flushed, the trace file closed.
  void close();

  ev3io::Logger log;
  ev3io::Signals signals;
  ev3io::UdpTransport net;
  TraceFile trace_file;
  Script script;
  Counters drops;
  bool state_failed = false;  ///< A state write failed: the program sends nothing more and exits.

 private:
  /// Signed mode: checks the datagram just received; true, with its trailer taken off, when it is
  /// signed with our key and new; otherwise counts the drop ("auth:replay") and false.
  bool authentic();
  int open_signing(const std::string& path);

  const char* program_;
  std::string bytes_;
  ev3io::Endpoint from_;
  std::unique_ptr<ev3proto::auth::Key> key_;
  std::unique_ptr<ev3proto::auth::Signer> signer_;
  /// Signed mode's check of what arrives: a slot for every sender id (1.5 MiB), so that no replay
  /// of old traffic from many ids can fill it.
  std::unique_ptr<ev3proto::auth::Verifier<65536>> opener_;
};

/// The drop counter of a datagram that does not decode, for the codec's reason @p r:
/// "decode:<reason>", spaces as '_' ("decode:bad_number").
std::string decode_drop_key(ev3proto::Reason r);

/// Printable form of datagram @p d for the log: at most 100 bytes, other than printable ASCII as
/// \xNN, "..." when cut.
std::string printable(std::string_view d);

/// The address of @p agent in @p reg as @p net knows it ("127.0.0.1:40001"); "" when unknown.
std::string agent_address(const std::map<std::uint16_t, ev3proto::RegistryEntry>& reg, std::uint16_t agent,
                          const ev3io::UdpTransport& net);

}  // namespace ev3prog
