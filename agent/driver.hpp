// ev3-agent --driver (docs/driver.md): the agent core on a virtual clock, NDJSON on stdin/stdout.
#pragma once

namespace ev3agent {

/// Runs the driver mode until stdin ends; returns the exit status.
int run_driver(int argc, char** argv);

}  // namespace ev3agent
