// ev3-sim: serves each simulated robot's ev3dev tree through FUSE and runs the world (docs/devices.md,
// "Simulator"). This file only does I/O: the command line, the world file, one FUSE session per
// robot, the control FIFO, signals, the clock and the snapshot/status files. Everything else
// (physics, driver emulation, faults, the picture) is the ev3sim library.
//
// One process, one thread, one event loop: ppoll() on every FUSE session's fd, the control FIFO
// and a signalfd, with the next clock tick as the timeout. A write that takes simulated time (a
// sensor mode change) is answered when the clock gets there; everything else at once.
#define FUSE_USE_VERSION 35
#include <fuse3/fuse_lowlevel.h>

#include <fcntl.h>
#include <grp.h>
#include <poll.h>
#include <signal.h>
#include <sys/signalfd.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "ev3io/log.hpp"
#include "exec.hpp"
#include "ev3sim/options.hpp"
#include "ev3sim/sim.hpp"
#include "ev3sim/svg.hpp"
#include "ev3sim/world.hpp"

namespace {

using namespace ev3sim;
using ev3io::kDebug;
using ev3io::kError;
using ev3io::kInfo;
using ev3io::kVerbose;

std::int64_t monotonic_us() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1000000 + ts.tv_nsec / 1000;
}

// An open attribute: sysfs fills the buffer on a read at offset 0 and serves later offsets from
// it, so a reader never sees two halves of different values. `event` is the node's notify count
// when the file was opened or last read from the start (kernfs keeps the same per open file): a
// poll reports POLLPRI | POLLERR while the node's count has moved past it.
struct FileHandle {
  Ino ino = 0;
  std::string data;
  bool filled = false;
  std::uint64_t event = 0;
  fuse_pollhandle* ph = nullptr;  // the kernel waits for a notify on this file
};

struct DirEntry {
  std::string name;
  Ino ino;
  mode_t type;
};

struct PendingWrite {
  fuse_req_t req;
  int err;
  std::size_t size;
  SimTime done_at;
};

struct App;

struct Mount {
  App* app = nullptr;
  Robot* robot = nullptr;
  std::size_t index = 0;  // the robot's place on the command line, from 1
  std::string dir;
  fuse_session* se = nullptr;
  fuse_buf buf{};
  bool mounted = false;
  std::set<FileHandle*> polled;  // open files with a poll handle, woken by the tree's notifies
};

// Simulated time follows the monotonic clock times --time-scale. When stepping cannot keep up,
// the simulation falls behind (it runs slower) instead of racing to catch up later.
struct Clock {
  std::int64_t start_us = 0;  // monotonic time at the start
  SimTime sim_start = 0;
  SimTime sim_end = 0;        // 0: no --duration
  double scale = 1;
  SimTime max_step = 0;       // most simulated time stepped at once
  SimTime behind = 0;         // simulated time given up so far
  bool reported = false;
};

struct App {
  SimOptions opt;
  Clock clock;
  std::unique_ptr<Sim> sim;
  std::vector<std::unique_ptr<Mount>> mounts;
  std::vector<PendingWrite> pending;
  ev3io::Logger log;
  uid_t uid = 0;        // the owner of every node (ev3-sim's user: root, as on a brick, when run as root)
  gid_t gid = 0;        // the group of nodes not given to group ev3dev
  gid_t group_gid = 0;  // group ev3dev's gid, or gid when the machine has no such group
};

Mount& mount_of(fuse_req_t req) { return *static_cast<Mount*>(fuse_req_userdata(req)); }

struct stat stat_of(const App& app, const Node& n) {
  struct stat st {};
  st.st_ino = n.ino;
  st.st_uid = n.uid ? *n.uid : app.uid;
  st.st_gid = n.gid ? *n.gid : n.ev3dev_group ? app.group_gid : app.gid;
  st.st_blksize = 4096;
  switch (n.kind) {
    case NodeKind::Dir:
      st.st_mode = S_IFDIR | n.mode;
      st.st_nlink = 2;
      break;
    case NodeKind::File:
      st.st_mode = S_IFREG | n.mode;
      st.st_nlink = 1;
      st.st_size = n.size;
      break;
    case NodeKind::Link:
      st.st_mode = S_IFLNK | n.mode;
      st.st_nlink = 1;
      st.st_size = static_cast<off_t>(n.target.size());
      break;
  }
  return st;
}

// --- FUSE operations (one robot's tree each) ---------------------------------------------------

void op_lookup(fuse_req_t req, fuse_ino_t parent, const char* name) {
  Mount& m = mount_of(req);
  const Ino ino = m.robot->tree().lookup(parent, name);
  if (!ino) {
    fuse_reply_err(req, ENOENT);
    return;
  }
  fuse_entry_param e{};
  e.ino = ino;
  e.generation = 1;
  e.attr = stat_of(*m.app, *m.robot->tree().node(ino));
  e.attr_timeout = 0;   // every change of the tree (an unplug) is seen at once
  e.entry_timeout = 0;
  fuse_reply_entry(req, &e);
}

void op_getattr(fuse_req_t req, fuse_ino_t ino, fuse_file_info*) {
  Mount& m = mount_of(req);
  const Node* n = m.robot->tree().node(ino);
  if (!n) {
    fuse_reply_err(req, ENOENT);
    return;
  }
  const struct stat st = stat_of(*m.app, *n);
  fuse_reply_attr(req, &st, 0);
}

void op_setattr(fuse_req_t req, fuse_ino_t ino, struct stat* attr, int to_set, fuse_file_info* fi) {
  // `echo x > attr` truncates first; sysfs ignores that, and the times. chmod and chown change the
  // node as kernfs keeps them (the kernel has already checked who may: default_permissions).
  std::optional<unsigned> mode;
  std::optional<std::uint32_t> uid, gid;
  if (to_set & FUSE_SET_ATTR_MODE) mode = attr->st_mode & 07777;
  if (to_set & FUSE_SET_ATTR_UID) uid = attr->st_uid;
  if (to_set & FUSE_SET_ATTR_GID) gid = attr->st_gid;
  if (mode || uid || gid) {
    if (int err = mount_of(req).robot->tree().set_attributes(ino, mode, uid, gid)) {
      fuse_reply_err(req, err);
      return;
    }
  }
  op_getattr(req, ino, fi);
}

void op_readlink(fuse_req_t req, fuse_ino_t ino) {
  const Node* n = mount_of(req).robot->tree().node(ino);
  if (!n || n->kind != NodeKind::Link) {
    fuse_reply_err(req, EINVAL);
    return;
  }
  fuse_reply_readlink(req, n->target.c_str());
}

void op_opendir(fuse_req_t req, fuse_ino_t ino, fuse_file_info* fi) {
  const Tree& t = mount_of(req).robot->tree();
  const Node* n = t.node(ino);
  if (!n || n->kind != NodeKind::Dir) {
    fuse_reply_err(req, ENOTDIR);
    return;
  }
  if (!n->alive) {
    fuse_reply_err(req, ENOENT);
    return;
  }
  auto* entries = new std::vector<DirEntry>{{".", ino, S_IFDIR}, {"..", n->parent, S_IFDIR}};
  for (const auto& [name, child] : n->children) {
    const Node* c = t.node(child);
    const mode_t type = c->kind == NodeKind::Dir ? S_IFDIR : c->kind == NodeKind::Link ? S_IFLNK : S_IFREG;
    entries->push_back({name, child, type});
  }
  fi->fh = reinterpret_cast<std::uint64_t>(entries);
  fuse_reply_open(req, fi);
}

void op_readdir(fuse_req_t req, fuse_ino_t, size_t size, off_t off, fuse_file_info* fi) {
  const auto& entries = *reinterpret_cast<std::vector<DirEntry>*>(fi->fh);
  std::vector<char> buf(size);
  std::size_t used = 0;
  for (std::size_t i = static_cast<std::size_t>(off); i < entries.size(); ++i) {
    struct stat st {};
    st.st_ino = entries[i].ino;
    st.st_mode = entries[i].type;
    const std::size_t need = fuse_add_direntry(req, buf.data() + used, size - used, entries[i].name.c_str(), &st,
                                               static_cast<off_t>(i + 1));
    if (need > size - used) break;
    used += need;
  }
  fuse_reply_buf(req, buf.data(), used);
}

void op_releasedir(fuse_req_t req, fuse_ino_t, fuse_file_info* fi) {
  delete reinterpret_cast<std::vector<DirEntry>*>(fi->fh);
  fuse_reply_err(req, 0);
}

void op_open(fuse_req_t req, fuse_ino_t ino, fuse_file_info* fi) {
  const int acc = fi->flags & O_ACCMODE;
  const int err = mount_of(req).robot->tree().open(ino, acc != O_WRONLY, acc != O_RDONLY);
  if (err) {
    fuse_reply_err(req, err);
    return;
  }
  fi->direct_io = 1;  // every read reaches the simulation (no page cache)
  fi->keep_cache = 0;
  auto* h = new FileHandle;
  h->ino = ino;
  h->event = mount_of(req).robot->tree().node(ino)->event;
  fi->fh = reinterpret_cast<std::uint64_t>(h);
  fuse_reply_open(req, fi);
}

void op_read(fuse_req_t req, fuse_ino_t ino, size_t size, off_t off, fuse_file_info* fi) {
  Mount& m = mount_of(req);
  auto* h = reinterpret_cast<FileHandle*>(fi->fh);
  if (off == 0 || !h->filled) {
    m.robot->set_now(m.app->sim->now());
    if (const Node* n = m.robot->tree().node(ino)) h->event = n->event;
    ReadResult r = m.robot->tree().read(ino);
    if (r.err) {
      fuse_reply_err(req, r.err);
      return;
    }
    h->data = std::move(r.data);
    h->filled = true;
    if (m.app->log.enabled(kVerbose)) {
      std::string v = h->data;
      while (!v.empty() && v.back() == '\n') v.pop_back();
      m.app->log.log(kVerbose, "%s: t=%.4f s: read %s -> '%s'", m.robot->name().c_str(),
                     static_cast<double>(m.app->sim->now()) / 1e6, m.robot->tree().path_of(ino).c_str(), v.c_str());
    }
  }
  const auto o = static_cast<std::size_t>(off);
  if (o >= h->data.size()) {
    fuse_reply_buf(req, nullptr, 0);
    return;
  }
  fuse_reply_buf(req, h->data.data() + o, std::min(size, h->data.size() - o));
}

void op_write(fuse_req_t req, fuse_ino_t ino, const char* data, size_t size, off_t, fuse_file_info*) {
  Mount& m = mount_of(req);
  App& app = *m.app;
  m.robot->set_now(app.sim->now());
  const WriteResult r = m.robot->tree().write(ino, std::string_view(data, size));
  if (app.log.enabled(kDebug)) {
    std::string v(data, size);
    while (!v.empty() && v.back() == '\n') v.pop_back();
    app.log.log(kDebug, "%s: t=%.4f s: write %s <- '%s': %s%s", m.robot->name().c_str(),
                static_cast<double>(app.sim->now()) / 1e6, m.robot->tree().path_of(ino).c_str(), v.c_str(), r.err ? std::strerror(r.err) : "ok",
                r.done_at > app.sim->now() ? " (answered later)" : "");
  }
  if (r.done_at > app.sim->now()) {
    app.pending.push_back({req, r.err, size, r.done_at});
    return;
  }
  if (r.err) fuse_reply_err(req, r.err);
  else fuse_reply_write(req, size);
}

void op_flush(fuse_req_t req, fuse_ino_t, fuse_file_info*) { fuse_reply_err(req, 0); }

void op_release(fuse_req_t req, fuse_ino_t, fuse_file_info* fi) {
  auto* h = reinterpret_cast<FileHandle*>(fi->fh);
  if (h->ph) fuse_pollhandle_destroy(h->ph);
  mount_of(req).polled.erase(h);
  delete h;
  fuse_reply_err(req, 0);
}

// sysfs's poll (kernfs_generic_poll): always readable and writable; POLLPRI and POLLERR as well
// once the attribute was notified after the file was opened or last read from the start. A poll
// handle is kept until the next notify of the attribute (wake_pollers).
void op_poll(fuse_req_t req, fuse_ino_t ino, fuse_file_info* fi, fuse_pollhandle* ph) {
  Mount& m = mount_of(req);
  auto* h = reinterpret_cast<FileHandle*>(fi->fh);
  const Node* n = m.robot->tree().node(ino);
  if (ph) {
    if (h->ph) fuse_pollhandle_destroy(h->ph);
    h->ph = ph;
    m.polled.insert(h);
  }
  unsigned revents = POLLIN | POLLRDNORM | POLLOUT | POLLWRNORM;
  if (!n || !n->alive || n->event != h->event) revents |= POLLPRI | POLLERR;
  fuse_reply_poll(req, revents);
}

// Tells the kernel about every attribute the trees notified since the last call: each poll
// handle waiting on one of them is used once (the kernel polls again and gets a new one).
void wake_pollers(App& app) {
  for (auto& mp : app.mounts) {
    Mount& m = *mp;
    const std::vector<Ino> changed = m.robot->tree().take_notified();
    if (changed.empty() || m.polled.empty()) continue;
    for (auto it = m.polled.begin(); it != m.polled.end();) {
      FileHandle* h = *it;
      if (std::find(changed.begin(), changed.end(), h->ino) == changed.end()) {
        ++it;
        continue;
      }
      fuse_lowlevel_notify_poll(h->ph);
      fuse_pollhandle_destroy(h->ph);
      h->ph = nullptr;
      it = m.polled.erase(it);
    }
  }
}

void op_refuse_create(fuse_req_t req, fuse_ino_t, const char*, mode_t, fuse_file_info*) { fuse_reply_err(req, EACCES); }
void op_refuse_mknod(fuse_req_t req, fuse_ino_t, const char*, mode_t, dev_t) { fuse_reply_err(req, EACCES); }
void op_refuse_mkdir(fuse_req_t req, fuse_ino_t, const char*, mode_t) { fuse_reply_err(req, EACCES); }
void op_refuse_unlink(fuse_req_t req, fuse_ino_t, const char*) { fuse_reply_err(req, EACCES); }

fuse_lowlevel_ops make_ops() {
  fuse_lowlevel_ops ops{};
  ops.lookup = op_lookup;
  ops.getattr = op_getattr;
  ops.setattr = op_setattr;
  ops.readlink = op_readlink;
  ops.opendir = op_opendir;
  ops.readdir = op_readdir;
  ops.releasedir = op_releasedir;
  ops.open = op_open;
  ops.read = op_read;
  ops.write = op_write;
  ops.flush = op_flush;
  ops.release = op_release;
  ops.poll = op_poll;
  ops.create = op_refuse_create;
  ops.mknod = op_refuse_mknod;
  ops.mkdir = op_refuse_mkdir;
  ops.unlink = op_refuse_unlink;
  ops.rmdir = op_refuse_unlink;
  return ops;
}

// --- files ---------------------------------------------------------------------------------------

bool read_file(const std::string& path, std::string& out) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return false;
  std::ostringstream ss;
  ss << in.rdbuf();
  out = ss.str();
  return true;
}

// The world file @p path read and checked into @p out: "" or the error to print.
std::string load_world(const std::string& path, World& out) {
  std::string text;
  if (!read_file(path, text)) return "cannot read the world file " + path + ": " + std::strerror(errno);
  return parse_world(text, path, out);
}

// ev3-sim world FILE: the world file checked and printed as JSON (world_json), for programs that
// draw it (the web view): exit 0, or 2 with the error.
int world_main(int argc, char** argv) {
  if (argc == 2 && (std::strcmp(argv[1], "--help") == 0 || std::strcmp(argv[1], "-h") == 0)) {
    std::fputs("usage: ev3-sim world FILE\n\nChecks the world file FILE as ev3-sim reads it and prints it as JSON "
               "(centimetres and degrees;\ndocs/devices.md, \"World files\"). Exit status: 0, 2 on a bad file.\n",
               stdout);
    return 0;
  }
  if (argc != 2) {
    std::fprintf(stderr, "ev3-sim world: expected one world file (usage: ev3-sim world FILE)\n");
    return 2;
  }
  World world;
  if (std::string e = load_world(argv[1], world); !e.empty()) {
    std::fprintf(stderr, "ev3-sim: %s\n", e.c_str());
    return 2;
  }
  std::fputs(world_json(world).c_str(), stdout);
  return 0;
}

// Writes @p path whole or not at all (a temporary file renamed over it).
bool write_file_atomic(const std::string& path, const std::string& data) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) return false;
    out << data;
    if (!out.flush()) return false;
  }
  return std::rename(tmp.c_str(), path.c_str()) == 0;
}

void write_outputs(App& app, const std::string& snapshot, const std::string& status) {
  if (!snapshot.empty()) {
    if (write_file_atomic(snapshot, snapshot_svg(*app.sim)))
      app.log.log(kInfo, "snapshot written to %s", snapshot.c_str());
    else
      app.log.log(kError, "cannot write the snapshot %s: %s", snapshot.c_str(), std::strerror(errno));
  }
  if (!status.empty()) {
    if (write_file_atomic(status, app.sim->status_json()))
      app.log.log(kDebug, "status written to %s", status.c_str());
    else
      app.log.log(kError, "cannot write the status %s: %s", status.c_str(), std::strerror(errno));
  }
}

// --- the control FIFO ------------------------------------------------------------------------

struct ControlFifo {
  int rfd = -1;
  int wfd = -1;  // our own writer: the FIFO never reports end-of-file between writers
  std::string partial;
};

std::string open_control(const std::string& path, ControlFifo& c) {
  struct stat st {};
  if (stat(path.c_str(), &st) == 0) {
    if (!S_ISFIFO(st.st_mode)) return path + " exists and is not a FIFO";
  } else if (mkfifo(path.c_str(), 0600) != 0) {
    return "cannot create the FIFO " + path + ": " + std::strerror(errno);
  }
  c.rfd = open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (c.rfd < 0) return "cannot open the FIFO " + path + ": " + std::strerror(errno);
  c.wfd = open(path.c_str(), O_WRONLY | O_NONBLOCK | O_CLOEXEC);
  return {};
}

bool run_control_line(App& app, const std::string& line) {
  if (line.find_first_not_of(" \t\r") == std::string::npos) return false;
  for (auto& m : app.mounts) m->robot->set_now(app.sim->now());
  const ControlResult r = app.sim->control(line);
  if (!r.ok) {
    app.log.log(kError, "control: error: %s", r.message.c_str());
    return false;
  }
  app.log.log(kInfo, "control: ok %s", r.message.c_str());
  switch (r.action) {
    case ControlAction::None: break;
    case ControlAction::Snapshot: {
      const std::string path = r.path.empty() ? app.opt.snapshot : r.path;
      if (path.empty()) app.log.log(kError, "control: snapshot: no file (give one or --snapshot)");
      else write_outputs(app, path, "");
      break;
    }
    case ControlAction::Status: {
      const std::string path = r.path.empty() ? app.opt.status : r.path;
      if (path.empty()) app.log.log(kError, "control: status: no file (give one or --status)");
      else write_outputs(app, "", path);
      break;
    }
    case ControlAction::Quit: return true;
  }
  return false;
}

// Reads what is in the FIFO; true when a `quit` came.
bool read_control(App& app, ControlFifo& c) {
  char buf[4096];
  bool quit = false;
  for (;;) {
    const ssize_t n = read(c.rfd, buf, sizeof buf);
    if (n <= 0) break;
    c.partial.append(buf, static_cast<std::size_t>(n));
  }
  std::size_t nl;
  while ((nl = c.partial.find('\n')) != std::string::npos) {
    const std::string line = c.partial.substr(0, nl);
    c.partial.erase(0, nl + 1);
    quit = run_control_line(app, line) || quit;
  }
  return quit;
}

// --- setup -----------------------------------------------------------------------------------

std::string mount_robot(App& app, Mount& m, const fuse_lowlevel_ops& ops) {
  struct stat st {};
  if (stat(m.dir.c_str(), &st) != 0) {
    if (mkdir(m.dir.c_str(), 0755) != 0)
      return "cannot create the mount point " + m.dir + ": " + std::strerror(errno);
  } else if (!S_ISDIR(st.st_mode)) {
    return m.dir + " is not a directory";
  }
  // The source names the robot (ev3-sim exec finds the trees by it); fuse's option parser takes
  // a backslash before a comma or a backslash literally.
  std::string source;
  for (char c : mount_source(m.index, m.robot->name())) {
    if (c == ',' || c == '\\') source += '\\';
    source += c;
  }
  std::string o = "default_permissions,auto_unmount,fsname=" + source + ",subtype=ev3-sim";
  if (app.opt.allow_other) o += ",allow_other";
  const char* argv[] = {"ev3-sim", "-o", o.c_str()};
  fuse_args args = FUSE_ARGS_INIT(3, const_cast<char**>(argv));
  m.se = fuse_session_new(&args, &ops, sizeof ops, &m);
  if (!m.se) return "fuse_session_new failed for " + m.dir;
  if (fuse_session_mount(m.se, m.dir.c_str()) != 0)
    return "cannot mount " + m.robot->name() + "'s tree on " + m.dir +
           " (is it a stale mount? fusermount3 -u " + m.dir + ")";
  m.mounted = true;
  return {};
}

// Steps the simulation up to the present (real time x scale), so that a request is stamped with
// the current simulated time.
void catch_up(App& app) {
  Clock& c = app.clock;
  SimTime target = c.sim_start - c.behind +
                   static_cast<SimTime>(static_cast<double>(monotonic_us() - c.start_us) * c.scale);
  if (c.sim_end && target > c.sim_end) target = c.sim_end;
  if (target > app.sim->now() + c.max_step) {
    c.behind += target - (app.sim->now() + c.max_step);
    target = app.sim->now() + c.max_step;
    if (!c.reported && c.behind > 1000000) {
      app.log.log(kInfo, "the simulation cannot keep up with time x%g: it runs slower", c.scale);
      c.reported = true;
    }
  }
  app.sim->advance_to(target);
}

void answer_due_writes(App& app, bool all) {
  std::vector<PendingWrite> keep;
  for (const PendingWrite& p : app.pending) {
    if (all || p.done_at <= app.sim->now()) {
      if (p.err) fuse_reply_err(p.req, p.err);
      else fuse_reply_write(p.req, p.size);
    } else {
      keep.push_back(p);
    }
  }
  app.pending.swap(keep);
}

int run(App& app) {
  SimOptions& opt = app.opt;
  // The signals: INT/TERM stop, USR1 writes the snapshot and the status.
  sigset_t mask;
  sigemptyset(&mask);
  sigaddset(&mask, SIGINT);
  sigaddset(&mask, SIGTERM);
  sigaddset(&mask, SIGUSR1);
  sigprocmask(SIG_BLOCK, &mask, nullptr);
  signal(SIGPIPE, SIG_IGN);
  const int sfd = signalfd(-1, &mask, SFD_NONBLOCK | SFD_CLOEXEC);
  if (sfd < 0) {
    app.log.log(kError, "signalfd: %s", std::strerror(errno));
    return 1;
  }
  ControlFifo control;
  if (!opt.control.empty()) {
    if (std::string e = open_control(opt.control, control); !e.empty()) {
      app.log.log(kError, "%s", e.c_str());
      return 1;
    }
  }
  static const fuse_lowlevel_ops ops = make_ops();
  bool stop = false;
  int status = 0;
  for (auto& m : app.mounts) {
    if (std::string e = mount_robot(app, *m, ops); !e.empty()) {
      app.log.log(kError, "%s", e.c_str());
      stop = true;  // unmount what is mounted, then exit 1
      status = 1;
      break;
    }
    app.log.log(kInfo, "%s: %s tree on %s at (%.1f, %.1f) heading %.1f", m->robot->name().c_str(),
                opt.gen == Generation::Stretch ? "stretch" : "jessie", m->dir.c_str(), m->robot->pose().p.x,
                m->robot->pose().p.y, rad2deg(m->robot->pose().heading));
  }
  if (!stop)
    app.log.log(kInfo, "running: %.0f Hz, time x%g%s", opt.rate_hz, opt.time_scale,
                opt.duration_s > 0 ? (", for " + std::to_string(opt.duration_s) + " s").c_str() : "");
  app.log.flush();

  const std::int64_t period_us = static_cast<std::int64_t>(1e6 / opt.rate_hz);
  Clock& clock = app.clock;
  clock.start_us = monotonic_us();
  clock.sim_start = app.sim->now();
  clock.sim_end = opt.duration_s > 0 ? clock.sim_start + static_cast<SimTime>(opt.duration_s * 1e6) : 0;
  clock.scale = opt.time_scale;
  clock.max_step = std::max<SimTime>(kStepUs, static_cast<SimTime>(static_cast<double>(period_us) * opt.time_scale) * 4);
  std::int64_t next_tick = clock.start_us + period_us;
  std::vector<pollfd> fds;
  while (!stop) {
    fds.clear();
    for (auto& m : app.mounts) fds.push_back({fuse_session_fd(m->se), POLLIN, 0});
    fds.push_back({sfd, POLLIN, 0});
    if (control.rfd >= 0) fds.push_back({control.rfd, POLLIN, 0});
    // Wake for the next tick, or sooner when a held write is due (its simulated time, in real time).
    std::int64_t wake = next_tick;
    for (const PendingWrite& p : app.pending)
      wake = std::min(wake, clock.start_us + static_cast<std::int64_t>(
                                                 static_cast<double>(p.done_at - clock.sim_start + clock.behind) /
                                                 clock.scale));
    const std::int64_t wait_us = std::max<std::int64_t>(0, wake - monotonic_us());
    timespec ts{static_cast<time_t>(wait_us / 1000000), static_cast<long>(wait_us % 1000000) * 1000};
    const int n = ppoll(fds.data(), fds.size(), &ts, nullptr);
    if (n < 0 && errno != EINTR) {
      app.log.log(kError, "ppoll: %s", std::strerror(errno));
      status = 1;
      break;
    }
    for (std::size_t i = 0; n > 0 && i < app.mounts.size(); ++i) {
      if (!(fds[i].revents & (POLLIN | POLLERR | POLLHUP))) continue;
      Mount& m = *app.mounts[i];
      const int r = fuse_session_receive_buf(m.se, &m.buf);
      if (r == -EINTR || r == -EAGAIN) continue;
      if (r <= 0 || fuse_session_exited(m.se)) {
        app.log.log(kError, "%s: the mount %s went away", m.robot->name().c_str(), m.dir.c_str());
        m.mounted = false;
        stop = true;
        status = 1;
        break;
      }
      catch_up(app);
      fuse_session_process_buf(m.se, &m.buf);
    }
    const std::size_t sig_i = app.mounts.size();
    if (n > 0 && (fds[sig_i].revents & POLLIN)) {
      signalfd_siginfo si{};
      while (read(sfd, &si, sizeof si) == static_cast<ssize_t>(sizeof si)) {
        if (si.ssi_signo == SIGUSR1) {
          write_outputs(app, opt.snapshot, opt.status);
        } else {
          app.log.log(kInfo, "stopping (signal %u)", si.ssi_signo);
          stop = true;
        }
      }
    }
    if (n > 0 && control.rfd >= 0 && (fds[sig_i + 1].revents & POLLIN)) {
      catch_up(app);
      stop = read_control(app, control) || stop;
    }

    const std::int64_t now_us = monotonic_us();
    if (!app.pending.empty()) {
      catch_up(app);
      answer_due_writes(app, false);
    }
    if (now_us >= next_tick) {
      catch_up(app);
      answer_due_writes(app, false);
      next_tick += period_us;
      if (next_tick < now_us) next_tick = now_us + period_us;
      if (clock.sim_end && app.sim->now() + kStepUs > clock.sim_end) {
        app.log.log(kInfo, "%.3f s simulated: done", static_cast<double>(app.sim->now() - clock.sim_start) / 1e6);
        stop = true;
      }
    }
    wake_pollers(app);
    app.log.tick(static_cast<ev3io::Millis>(now_us / 1000));
  }
  answer_due_writes(app, true);
  if (status == 0) write_outputs(app, opt.snapshot, opt.status);
  for (auto& m : app.mounts) {
    if (m->se) {
      if (m->mounted) fuse_session_unmount(m->se);
      fuse_session_destroy(m->se);
    }
    free(m->buf.mem);
  }
  if (control.rfd >= 0) close(control.rfd);
  if (control.wfd >= 0) close(control.wfd);
  close(sfd);
  app.log.flush();
  return status;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc > 1 && std::strcmp(argv[1], "exec") == 0) return exec_main(argc - 1, argv + 1);
  if (argc > 1 && std::strcmp(argv[1], "world") == 0) return world_main(argc - 1, argv + 1);
  App app;
  app.log.set_name("sim");
  std::string err = parse_sim_options(argc, argv, app.opt);
  if (!err.empty()) {
    std::fprintf(stderr, "ev3-sim: %s (try --help)\n", err.c_str());
    return 2;
  }
  if (app.opt.help) {
    std::fputs(sim_usage().c_str(), stdout);
    return 0;
  }
  app.log.set_level(app.opt.log_level);
  if (!app.opt.log_file.empty() && !app.log.open(app.opt.log_file)) {
    std::fprintf(stderr, "ev3-sim: cannot open the log file %s: %s\n", app.opt.log_file.c_str(), std::strerror(errno));
    return 2;
  }
  World world;
  if (std::string e = load_world(app.opt.world, world); !e.empty()) {
    std::fprintf(stderr, "ev3-sim: %s\n", e.c_str());
    return 2;
  }
  app.sim = std::make_unique<Sim>(world);
  for (std::size_t i = 0; i < app.opt.robots.size(); ++i) {
    const RobotOptions& ro = app.opt.robots[i];
    RobotConfig cfg;
    cfg.name = ro.name;
    cfg.gen = app.opt.gen;
    cfg.seed = app.opt.seed + i;
    cfg.battery.full_volts = app.opt.battery_volts;
    cfg.battery.capacity_mah = app.opt.battery_mah;
    if (ro.pose) {
      cfg.start = *ro.pose;
    } else if (i < world.starts.size()) {
      cfg.start.p = {world.starts[i].x, world.starts[i].y};
      cfg.start.heading = wrap_angle(deg2rad(world.starts[i].heading_deg));
    } else {
      std::fprintf(stderr, "ev3-sim: %s has no start pose: give --robot X,Y,HEADING or a 'start' line in %s\n",
                   ro.name.c_str(), app.opt.world.c_str());
      return 2;
    }
    if (std::string e = app.sim->add_robot(cfg); !e.empty()) {
      std::fprintf(stderr, "ev3-sim: %s: %s\n", app.opt.world.c_str(), e.c_str());
      return 2;
    }
    auto m = std::make_unique<Mount>();
    m->app = &app;
    m->robot = app.sim->robot(ro.name);
    m->index = i + 1;
    m->dir = ro.root;
    app.mounts.push_back(std::move(m));
  }
  if (access("/dev/fuse", R_OK | W_OK) != 0) {
    std::fprintf(stderr,
                 "ev3-sim: /dev/fuse is missing or not usable (%s): ev3-sim serves the ev3dev tree through FUSE; "
                 "load the fuse module (modprobe fuse) or give the container the device (--device /dev/fuse)\n",
                 std::strerror(errno));
    return 1;
  }
  app.uid = getuid();
  app.gid = getgid();
  // The class devices' attributes belong to group ev3dev, as ev3dev's udev rules leave them on a
  // brick; a machine without that group gets ev3-sim's own group instead (nothing is created).
  if (const group* g = getgrnam("ev3dev")) {
    app.group_gid = g->gr_gid;
  } else {
    app.group_gid = app.gid;
    app.log.log(kInfo, "no group ev3dev on this machine: the attributes a brick gives to group ev3dev are group %u",
                static_cast<unsigned>(app.gid));
  }
  return run(app);
}
