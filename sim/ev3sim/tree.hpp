/// @file tree.hpp
/// @brief A sysfs-like tree of directories, attribute files and symlinks, with the kernel's
///        answers (errno values) but no I/O: ev3-sim serves it through FUSE, the tests call it
///        directly. Each node keeps its inode number for the life of the process; a removed
///        node is "dead": it can no longer be looked up, and reading or writing it through a
///        descriptor opened before fails with ENODEV, as sysfs does after a device is unplugged.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

namespace ev3sim {

using Ino = std::uint64_t;
/// Simulated time in microseconds.
using SimTime = std::int64_t;

/// What a read of an attribute gives: its bytes, or an errno.
struct ReadResult {
  int err = 0;
  std::string data;
};

/// What a write of an attribute gives: 0 or an errno, and when the write returns. A write that
/// takes simulated time (a sensor mode change) has done_at > 0: the caller holds the writer until
/// the simulation reaches that time, then answers with err.
struct WriteResult {
  int err = 0;
  SimTime done_at = 0;
};

using ReadFn = std::function<ReadResult()>;
using WriteFn = std::function<WriteResult(std::string_view)>;

enum class NodeKind { Dir, File, Link };

struct Node {
  Ino ino = 0;
  Ino parent = 0;
  std::string name;
  NodeKind kind = NodeKind::Dir;
  unsigned mode = 0755;           ///< permission bits as sysfs shows them (chmod changes them)
  /// Owned by group ev3dev (ev3dev's udev rules give the class devices' attributes to it); the
  /// program maps this to a gid. Otherwise the group is the owner's.
  bool ev3dev_group = false;
  std::optional<std::uint32_t> uid;  ///< set by chown; unset: the program's default owner
  std::optional<std::uint32_t> gid;  ///< set by chown; unset: see ev3dev_group
  std::uint64_t event = 0;        ///< sysfs_notify count: pollers wake when it moves
  std::uint32_t size = 4096;      ///< st_size (sysfs: 4096 for attributes, N for binary ones)
  std::map<std::string, Ino> children;
  std::string target;             ///< symlink target
  ReadFn read;                    ///< files: nullptr when not readable
  WriteFn write;                  ///< files: nullptr when not writable
  bool alive = true;
};

class Tree {
 public:
  static constexpr Ino kRoot = 1;
  Tree();

  /// The node (dead ones too), or nullptr.
  const Node* node(Ino ino) const;
  /// The live child @p name of directory @p parent, or 0.
  Ino lookup(Ino parent, std::string_view name) const;
  /// The live node at @p path (relative to the root, '/'-separated, no symlinks followed), or 0.
  Ino resolve(std::string_view path) const;
  /// The path of a live node, relative to the root.
  std::string path_of(Ino ino) const;

  /// Creates the directories of @p path that are missing; returns the last one.
  Ino mkdirs(std::string_view path);
  /// Adds (or replaces) a file. @p size is its st_size.
  Ino add_file(std::string_view path, unsigned mode, ReadFn read, WriteFn write,
               std::uint32_t size = 4096);
  /// Adds a symlink; @p target is written as given (sysfs links are relative).
  Ino add_link(std::string_view path, std::string target);
  /// Adds a symlink at @p path pointing at @p to (both relative to the root) with a relative target.
  Ino add_relative_link(std::string_view path, std::string_view to);
  /// Removes the node and everything under it (they become dead).
  void remove(Ino ino);
  /// Bumped by every change of structure (for caches).
  std::uint64_t version() const { return version_; }
  /// ev3dev's udev rules on a class device: every attribute file under the directory @p dir (or
  /// the file @p dir itself) goes to group ev3dev with the owner's permission bits copied to the
  /// group's (0644 -> 0664, 0200 -> 0220, 0444 -> 0444). Directories and symlinks stay as they are.
  void give_to_ev3dev_group(Ino dir);

  /// sysfs_notify: the attribute changed in a way pollers wait for (POLLPRI, POLLERR). Counts
  /// the node's event and queues it for take_notified().
  void notify(Ino ino);
  /// The nodes notified since the last call (each once), in the order of their first notify.
  std::vector<Ino> take_notified();

  /// chmod / chown as sysfs allows them to whoever the kernel let through (the owner or root for
  /// chmod, root for chown; the caller checks that): the permission bits of a file or directory
  /// (not a symlink: EPERM), its owner, its group. 0, ENOENT, or ENODEV for a dead node.
  int set_attributes(Ino ino, std::optional<unsigned> mode, std::optional<std::uint32_t> uid,
                     std::optional<std::uint32_t> gid);

  // --- the file operations, with sysfs's errors --------------------------------------------
  /// 0, ENODEV (dead node), EISDIR, or EACCES when the attribute cannot be read (or written).
  int open(Ino ino, bool for_read, bool for_write) const;
  ReadResult read(Ino ino) const;
  WriteResult write(Ino ino, std::string_view data) const;

 private:
  Node& make(Ino parent, std::string_view name, NodeKind kind);
  std::unordered_map<Ino, Node> nodes_;
  Ino next_ = kRoot + 1;
  std::uint64_t version_ = 0;
  std::vector<Ino> notified_;
};

/// The relative symlink target that leads from directory @p from_dir to @p to (both relative
/// to the same root), spelled as kernfs spells it: up until an ancestor of the target's parent,
/// then down. relative_target("class/leds", "devices/platform/leds/x") is
/// "../../devices/platform/leds/x"; from "a/b/c/d" to its grandparent "a/b" it is "../../../b".
std::string relative_target(std::string_view from_dir, std::string_view to);

/// The blank-separated words of @p s (spaces, tabs, newlines).
std::vector<std::string> split_words(std::string_view s);
/// sysfs_streq: equal, ignoring one trailing newline on either side.
bool sysfs_streq(std::string_view a, std::string_view b);
/// kstrtoint/kstrtol in base 10 (an optional sign, digits, an optional trailing newline):
/// 0, EINVAL, or ERANGE when outside [lo, hi].
int parse_kernel_int(std::string_view s, long long lo, long long hi, long long& out);

}  // namespace ev3sim
