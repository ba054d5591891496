#include "ev3sim/tree.hpp"

#include <algorithm>
#include <cerrno>

namespace ev3sim {

namespace {

std::vector<std::string_view> split_path(std::string_view path) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < path.size()) {
    std::size_t j = path.find('/', i);
    if (j == std::string_view::npos) j = path.size();
    if (j > i) out.push_back(path.substr(i, j - i));
    i = j + 1;
  }
  return out;
}

}  // namespace

Tree::Tree() {
  Node root;
  root.ino = kRoot;
  root.parent = kRoot;
  root.kind = NodeKind::Dir;
  root.mode = 0755;
  nodes_.emplace(kRoot, std::move(root));
}

const Node* Tree::node(Ino ino) const {
  auto it = nodes_.find(ino);
  return it == nodes_.end() ? nullptr : &it->second;
}

Ino Tree::lookup(Ino parent, std::string_view name) const {
  const Node* p = node(parent);
  if (!p || !p->alive || p->kind != NodeKind::Dir) return 0;
  auto it = p->children.find(std::string(name));
  return it == p->children.end() ? 0 : it->second;
}

Ino Tree::resolve(std::string_view path) const {
  Ino cur = kRoot;
  for (std::string_view part : split_path(path)) {
    cur = lookup(cur, part);
    if (!cur) return 0;
  }
  return cur;
}

std::string Tree::path_of(Ino ino) const {
  std::string out;
  while (ino != kRoot) {
    const Node* n = node(ino);
    if (!n) return {};
    out = out.empty() ? n->name : n->name + "/" + out;
    ino = n->parent;
  }
  return out;
}

Node& Tree::make(Ino parent, std::string_view name, NodeKind kind) {
  Node& p = nodes_.at(parent);
  auto existing = p.children.find(std::string(name));
  if (existing != p.children.end()) remove(existing->second);
  Node n;
  n.ino = next_++;
  n.parent = parent;
  n.name = std::string(name);
  n.kind = kind;
  nodes_.at(parent).children.emplace(n.name, n.ino);
  ++version_;
  return nodes_.emplace(n.ino, std::move(n)).first->second;
}

Ino Tree::mkdirs(std::string_view path) {
  Ino cur = kRoot;
  for (std::string_view part : split_path(path)) {
    Ino next = lookup(cur, part);
    if (next) {
      if (nodes_.at(next).kind != NodeKind::Dir) return 0;
    } else {
      Node& d = make(cur, part, NodeKind::Dir);
      d.mode = 0755;
      next = d.ino;
    }
    cur = next;
  }
  return cur;
}

Ino Tree::add_file(std::string_view path, unsigned mode, ReadFn read, WriteFn write,
                   std::uint32_t size) {
  const std::size_t slash = path.rfind('/');
  const Ino dir = slash == std::string_view::npos ? kRoot : mkdirs(path.substr(0, slash));
  Node& f = make(dir, slash == std::string_view::npos ? path : path.substr(slash + 1), NodeKind::File);
  f.mode = mode;
  f.size = size;
  f.read = std::move(read);
  f.write = std::move(write);
  return f.ino;
}

Ino Tree::add_link(std::string_view path, std::string target) {
  const std::size_t slash = path.rfind('/');
  const Ino dir = slash == std::string_view::npos ? kRoot : mkdirs(path.substr(0, slash));
  Node& l = make(dir, slash == std::string_view::npos ? path : path.substr(slash + 1), NodeKind::Link);
  l.mode = 0777;
  l.size = static_cast<std::uint32_t>(target.size());
  l.target = std::move(target);
  return l.ino;
}

Ino Tree::add_relative_link(std::string_view path, std::string_view to) {
  const std::size_t slash = path.rfind('/');
  const std::string_view dir = slash == std::string_view::npos ? std::string_view{} : path.substr(0, slash);
  return add_link(path, relative_target(dir, to));
}

void Tree::remove(Ino ino) {
  if (ino == kRoot) return;
  auto it = nodes_.find(ino);
  if (it == nodes_.end() || !it->second.alive) return;
  std::vector<Ino> stack{ino};
  while (!stack.empty()) {
    Node& n = nodes_.at(stack.back());
    stack.pop_back();
    n.alive = false;
    for (auto& [name, child] : n.children) stack.push_back(child);
    n.children.clear();
  }
  Node& parent = nodes_.at(it->second.parent);
  parent.children.erase(it->second.name);
  ++version_;
}

void Tree::give_to_ev3dev_group(Ino dir) {
  std::vector<Ino> stack{dir};
  while (!stack.empty()) {
    Node& n = nodes_.at(stack.back());
    stack.pop_back();
    if (n.kind == NodeKind::File) {
      n.ev3dev_group = true;
      n.mode = (n.mode & ~0070u) | ((n.mode & 0700u) >> 3);
    }
    for (const auto& [name, child] : n.children) stack.push_back(child);
  }
}

void Tree::notify(Ino ino) {
  auto it = nodes_.find(ino);
  if (it == nodes_.end() || !it->second.alive) return;
  Node& n = it->second;
  // Queued once until taken: a node already counted since the last take is in the queue.
  if (std::find(notified_.begin(), notified_.end(), ino) == notified_.end()) notified_.push_back(ino);
  ++n.event;
}

std::vector<Ino> Tree::take_notified() {
  std::vector<Ino> out;
  out.swap(notified_);
  return out;
}

int Tree::set_attributes(Ino ino, std::optional<unsigned> mode, std::optional<std::uint32_t> uid,
                         std::optional<std::uint32_t> gid) {
  auto it = nodes_.find(ino);
  if (it == nodes_.end()) return ENOENT;
  Node& n = it->second;
  if (!n.alive) return ENODEV;
  if (mode && n.kind == NodeKind::Link) return EPERM;
  if (mode) n.mode = *mode & 07777u;
  if (uid) n.uid = *uid;
  if (gid) n.gid = *gid;
  return 0;
}

int Tree::open(Ino ino, bool for_read, bool for_write) const {
  const Node* n = node(ino);
  if (!n) return ENOENT;
  if (!n->alive) return ENODEV;
  if (n->kind == NodeKind::Dir) return for_write ? EISDIR : 0;
  if (n->kind == NodeKind::Link) return ELOOP;
  // sysfs refuses to open for reading an attribute without a show method, and for writing one
  // without a store method, whatever the caller's privileges.
  if (for_read && !n->read) return EACCES;
  if (for_write && !n->write) return EACCES;
  return 0;
}

ReadResult Tree::read(Ino ino) const {
  const Node* n = node(ino);
  if (!n) return {ENOENT, {}};
  if (!n->alive) return {ENODEV, {}};
  if (n->kind == NodeKind::Dir) return {EISDIR, {}};
  if (!n->read) return {EACCES, {}};
  return n->read();
}

WriteResult Tree::write(Ino ino, std::string_view data) const {
  const Node* n = node(ino);
  if (!n) return {ENOENT, 0};
  if (!n->alive) return {ENODEV, 0};
  if (n->kind == NodeKind::Dir) return {EISDIR, 0};
  if (!n->write) return {EACCES, 0};
  return n->write(data);
}

std::string relative_target(std::string_view from_dir, std::string_view to) {
  // kernfs's spelling (kernfs_get_target_path): up from the link's directory until it is an
  // ancestor of (or equal to) the target's parent, then down to the target.
  auto dirname = [](std::string_view p) {
    const std::size_t s = p.rfind('/');
    return s == std::string_view::npos ? std::string_view{} : p.substr(0, s);
  };
  const std::string_view target_parent = dirname(to);
  std::string_view base = from_dir;
  std::string out;
  while (!base.empty() &&
         !(target_parent == base ||
           (target_parent.size() > base.size() && target_parent.substr(0, base.size()) == base &&
            target_parent[base.size()] == '/'))) {
    base = dirname(base);
    out += "../";
  }
  out += base.empty() ? to : to.substr(base.size() + 1);
  return out;
}

std::vector<std::string> split_words(std::string_view s) {
  std::vector<std::string> out;
  auto blank = [](char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; };
  std::size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && blank(s[i])) ++i;
    std::size_t j = i;
    while (j < s.size() && !blank(s[j])) ++j;
    if (j > i) out.emplace_back(s.substr(i, j - i));
    i = j;
  }
  return out;
}

bool sysfs_streq(std::string_view a, std::string_view b) {
  if (!a.empty() && a.back() == '\n') a.remove_suffix(1);
  if (!b.empty() && b.back() == '\n') b.remove_suffix(1);
  return a == b;
}

int parse_kernel_int(std::string_view s, long long lo, long long hi, long long& out) {
  if (!s.empty() && s.back() == '\n') s.remove_suffix(1);
  bool neg = false;
  std::size_t i = 0;
  if (i < s.size() && (s[i] == '+' || s[i] == '-')) neg = s[i++] == '-';
  if (i >= s.size()) return EINVAL;
  unsigned long long v = 0;
  bool overflow = false;
  for (; i < s.size(); ++i) {
    if (s[i] < '0' || s[i] > '9') return EINVAL;
    if (v > (~0ULL - 9) / 10) overflow = true;
    v = v * 10 + static_cast<unsigned>(s[i] - '0');
  }
  if (overflow || v > (1ULL << 62)) return ERANGE;
  const long long sv = neg ? -static_cast<long long>(v) : static_cast<long long>(v);
  if (sv < lo || sv > hi) return ERANGE;
  out = sv;
  return 0;
}

}  // namespace ev3sim
