// ev3-sim exec: runs a program with one simulated robot's tree in place of the brick's
// /sys/class (docs/devices.md, "Running a brick's program"). The choice of the tree is
// ev3sim's (options.cpp: the mounts in /proc/self/mountinfo); this file makes the namespace.
//
// In a private mount namespace (unshare(CLONE_NEWNS), every mount made private so nothing leaks
// back), the robot's DIR/class is bind-mounted on /sys/class and DIR/devices on /sys/devices:
// the class directories hold symlinks such as ../../devices/platform/..., which must lead into the
// same tree. Then the command replaces this process (its exit status is the command's).
#include "exec.hpp"

#include <sched.h>
#include <stdlib.h>
#include <sys/mount.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <climits>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "ev3sim/options.hpp"

namespace {

int fail(const std::string& why) {
  std::fprintf(stderr, "ev3-sim %s\n", why.c_str());
  return 1;
}

// "" when @p p is a directory, else why not.
std::string not_dir(const std::string& p) {
  struct stat st {};
  if (stat(p.c_str(), &st) != 0) return std::strerror(errno);
  return S_ISDIR(st.st_mode) ? "" : "not a directory";
}

}  // namespace

int exec_main(int argc, char** argv) {
  ev3sim::ExecOptions opt;
  if (std::string e = ev3sim::parse_exec_options(argc, argv, opt); !e.empty()) {
    std::fprintf(stderr, "ev3-sim %s (try ev3-sim exec --help)\n", e.c_str());
    return 2;
  }
  if (opt.help) {
    std::fputs(ev3sim::exec_usage().c_str(), stdout);
    return 0;
  }
  if (geteuid() != 0)
    return fail("exec: needs root: it makes a private mount namespace and bind-mounts the robot's tree on "
                "/sys/class (run it with sudo)");
  std::string real_root;
  if (!opt.root.empty()) {
    char buf[PATH_MAX];
    if (!realpath(opt.root.c_str(), buf))
      return fail("exec: --sysfs-root " + opt.root + ": " + std::strerror(errno));
    real_root = buf;
  }
  std::ifstream in("/proc/self/mountinfo");
  if (!in) return fail(std::string("exec: cannot read /proc/self/mountinfo: ") + std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  ev3sim::SimMount m;
  if (std::string e = ev3sim::pick_sim_mount(ev3sim::parse_sim_mounts(text.str()), opt, real_root, m); !e.empty())
    return fail(e);

  if (unshare(CLONE_NEWNS) != 0)
    return fail(std::string("exec: unshare(CLONE_NEWNS) refused: ") + std::strerror(errno) +
                " (in a container it needs CAP_SYS_ADMIN)");
  if (mount(nullptr, "/", nullptr, MS_REC | MS_PRIVATE, nullptr) != 0)
    return fail(std::string("exec: cannot make the mounts private: ") + std::strerror(errno));
  for (const char* sub : {"class", "devices"}) {
    const std::string from = m.dir + "/" + sub;
    const std::string to = std::string("/sys/") + sub;
    if (std::string why = not_dir(from); !why.empty())
      return fail("exec: " + from + ": " + why + " (a tree ev3-sim serves to another user needs its --allow-other)");
    if (std::string why = not_dir(to); !why.empty()) return fail("exec: " + to + ": " + why + " (is sysfs mounted on /sys?)");
    if (mount(from.c_str(), to.c_str(), nullptr, MS_BIND, nullptr) != 0)
      return fail("exec: cannot bind-mount " + from + " on " + to + ": " + std::strerror(errno));
  }
  std::vector<char*> args;
  for (std::string& a : opt.command) args.push_back(a.data());
  args.push_back(nullptr);
  execvp(args[0], args.data());
  const int err = errno;
  std::fprintf(stderr, "ev3-sim exec: cannot run %s: %s\n", args[0], std::strerror(err));
  return err == ENOENT ? 127 : 126;
}
