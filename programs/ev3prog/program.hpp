/// @file program.hpp
/// @brief The main() of ev3-agent and ev3-master, written once: `--driver` anywhere on the command
///        line selects the driver mode (docs/driver.md), otherwise the options are parsed (usage on
///        --help, a clear error and exit status 2 on a bad flag) and the program runs.
#pragma once

#include <cstdio>
#include <cstring>
#include <string>

#include "ev3io/cli.hpp"
#include "ev3prog/driver_json.hpp"

namespace ev3prog {

/// A program's main(): @p name ("ev3-agent") for the messages; @p run_driver the driver mode;
/// @p parse the options parser; @p run the program with its options (it keeps its state in a
/// static: the cores are large).
template <typename Options>
int program_main(int argc, char** argv, const char* name, int (*run_driver)(int, char**),
                 ev3io::ParseOutcome (*parse)(int, const char* const*, Options&, std::string&),
                 int (*run)(const Options&)) {
  for (int i = 1; i < argc; ++i)
    if (std::strcmp(argv[i], "--driver") == 0) return run_driver(argc, argv);
  Options o;
  std::string msg;
  switch (parse(argc, argv, o, msg)) {
    case ev3io::ParseOutcome::help: std::printf("%s", msg.c_str()); return 0;
    case ev3io::ParseOutcome::error:
      std::fprintf(stderr, "%s: %s (try --help)\n", name, msg.c_str());
      return 2;
    case ev3io::ParseOutcome::run: break;
  }
  return run(o);
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

}  // namespace ev3prog
