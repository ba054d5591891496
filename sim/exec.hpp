// ev3-sim exec (exec.cpp): a command with a simulated robot's tree as /sys/class.
#pragma once

/// Runs `ev3-sim exec ...` (argv[0] is "exec"); returns only on an error, with the exit status.
int exec_main(int argc, char** argv);
