// ev3-master --driver (docs/driver.md): the master core on a virtual clock, NDJSON on stdin/stdout.
#pragma once

namespace ev3master {

/// Runs the driver mode until stdin ends; returns the exit status.
int run_driver(int argc, char** argv);

}  // namespace ev3master
