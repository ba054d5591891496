/// @file program.hpp
/// @brief What ev3-agent and ev3-master do alike around their cores, written once: main()
///        (`--driver` anywhere on the command line selects the driver mode, docs/driver.md;
///        otherwise the options are parsed: usage on --help, a clear error and exit status 2 on a bad
///        flag), the driver mode's main, opening the log and trace outputs, loading a console script,
///        an agent's address for the operator.
#pragma once

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <map>
#include <string>
#include <string_view>

#include <ev3proto/master.hpp>

#include "ev3io/cli.hpp"
#include "ev3io/log.hpp"
#include "ev3io/loop.hpp"
#include "ev3io/udp.hpp"
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

/// The receive side of a program's event loop: it reads at most kBatch datagrams before the loop
/// sends what it owes (answers, resends, the copies due), acts on the deadlines due and writes its
/// status, so a flood cannot starve them.
class Receiver {
 public:
  static constexpr std::size_t kBatch = 64;
  /// Reads up to kBatch datagrams from @p net, each to @p on(bytes, from, now). True when it stopped
  /// at the bound: the socket may hold more, and the loop must not sleep before reading on.
  template <typename On>
  bool read(ev3io::UdpTransport& net, On&& on) {
    for (std::size_t n = 0; n < kBatch; ++n) {
      if (!net.receive(bytes_, from_)) return false;
      on(bytes_, from_, ev3io::monotonic_ms());
    }
    return true;
  }

 private:
  std::string bytes_;
  ev3io::Endpoint from_;
};

/// Opens what a program writes first: the logger (named @p log_name, at --log-level, into
/// --log-file when given, else stderr) and the --trace file when given. False after saying on stderr
/// what could not be opened ("@p program: bad value for --log-file: cannot open 'F': reason").
bool open_outputs(const char* program, const char* log_name, const ev3io::CommonOptions& o, ev3io::Logger& log,
                  TraceFile& trace);

/// Writes @p text to the state file @p path (atomically: ev3io::write_state_file). False after
/// saying in the log and on stderr that @p what is not on disk and that the program sends nothing
/// more ("@p program: reason; the election state is not on disk: sending nothing more, exiting").
bool save_state_file(const char* program, const char* what, const std::string& path, std::string_view text,
                     ev3io::Logger& log);

/// Loads the console script @p path (given with @p flag, "--script") into @p script; nothing when
/// @p path is empty. False after saying on stderr why it cannot be read.
bool load_script(const char* program, const char* flag, const std::string& path, Script& script);

/// The address of @p agent in @p reg as @p net knows it ("127.0.0.1:40001"); "" when unknown.
std::string agent_address(const std::map<std::uint16_t, ev3proto::RegistryEntry>& reg, std::uint16_t agent,
                          const ev3io::UdpTransport& net);

}  // namespace ev3prog
