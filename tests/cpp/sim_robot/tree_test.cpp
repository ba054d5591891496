// The sysfs-like tree: kernfs's symlink spelling, open/read/write errors, dead nodes after an
// unplug, the kernel's integer parsing; the geometry under the physics; the command line.
#include <gtest/gtest.h>

#include <cerrno>

#include "ev3sim/geometry.hpp"
#include "ev3sim/options.hpp"
#include "ev3sim/tree.hpp"

namespace {

using namespace ev3sim;

TEST(Tree, KernfsLinkSpelling) {
  EXPECT_EQ(relative_target("class/tacho-motor", "devices/platform/x/motor0"), "../../devices/platform/x/motor0");
  // A device's `device` link to its parent's parent: up to the target's parent, then down.
  EXPECT_EQ(relative_target("d/port5/m:outB/tacho-motor/motor0", "d/port5/m:outB"), "../../../m:outB");
  EXPECT_EQ(relative_target("devices/platform/leds/leds/led0", "devices/platform/leds"), "../../../leds");
  EXPECT_EQ(relative_target("devices/platform/leds/leds/led0", "class/leds"), "../../../../../class/leds");
}

TEST(Tree, FilesLinksAndErrors) {
  Tree t;
  int value = 7;
  const Ino ro = t.add_file("a/b/ro", 0444, [&] { return ReadResult{0, std::to_string(value) + "\n"}; }, nullptr);
  const Ino wo = t.add_file("a/b/wo", 0200, nullptr, [&](std::string_view d) {
    value = static_cast<int>(d.size());
    return WriteResult{};
  });
  const Ino link = t.add_relative_link("c/link", "a/b");
  EXPECT_EQ(t.resolve("a/b/ro"), ro);
  EXPECT_EQ(t.node(link)->target, "../a/b");
  EXPECT_EQ(t.path_of(wo), "a/b/wo");
  EXPECT_EQ(t.open(ro, true, false), 0);
  EXPECT_EQ(t.open(ro, false, true), EACCES);  // no store method
  EXPECT_EQ(t.open(wo, true, false), EACCES);  // no show method
  EXPECT_EQ(t.open(t.resolve("a"), false, true), EISDIR);
  EXPECT_EQ(t.write(wo, "abc").err, 0);
  EXPECT_EQ(t.read(ro).data, "3\n");
  EXPECT_EQ(t.read(wo).err, EACCES);
  // Removing a directory kills everything under it: gone by name, ENODEV through held nodes.
  const auto version = t.version();
  t.remove(t.resolve("a/b"));
  EXPECT_GT(t.version(), version);
  EXPECT_EQ(t.resolve("a/b/ro"), 0u);
  EXPECT_EQ(t.lookup(t.resolve("a"), "b"), 0u);
  EXPECT_EQ(t.read(ro).err, ENODEV);
  EXPECT_EQ(t.write(wo, "x").err, ENODEV);
  EXPECT_EQ(t.open(ro, true, false), ENODEV);
  // A new node never reuses an inode number.
  const Ino again = t.add_file("a/b/ro", 0444, [] { return ReadResult{0, "new\n"}; }, nullptr);
  EXPECT_GT(again, link);
  EXPECT_EQ(t.read(ro).err, ENODEV);
  EXPECT_EQ(t.read(again).data, "new\n");
}

TEST(Tree, Ev3devGroupChmodChownAndNotify) {
  Tree t;
  const Ino rw = t.add_file("d/m/speed_sp", 0644, [] { return ReadResult{}; }, [](std::string_view) { return WriteResult{}; });
  const Ino wo = t.add_file("d/m/command", 0200, nullptr, [](std::string_view) { return WriteResult{}; });
  const Ino ro = t.add_file("d/m/sub/state", 0444, [] { return ReadResult{}; }, nullptr);
  const Ino link = t.add_relative_link("d/m/subsystem", "class/x");
  const Ino outside = t.add_file("d/other", 0644, [] { return ReadResult{}; }, nullptr);
  t.give_to_ev3dev_group(t.resolve("d/m"));
  // udev's g=u on every attribute below the device; directories, links and others untouched.
  EXPECT_EQ(t.node(rw)->mode, 0664u);
  EXPECT_EQ(t.node(wo)->mode, 0220u);
  EXPECT_EQ(t.node(ro)->mode, 0444u);
  EXPECT_TRUE(t.node(rw)->ev3dev_group && t.node(wo)->ev3dev_group && t.node(ro)->ev3dev_group);
  EXPECT_FALSE(t.node(t.resolve("d/m"))->ev3dev_group);
  EXPECT_EQ(t.node(t.resolve("d/m"))->mode, 0755u);
  EXPECT_FALSE(t.node(link)->ev3dev_group);
  EXPECT_FALSE(t.node(outside)->ev3dev_group);
  EXPECT_EQ(t.node(outside)->mode, 0644u);

  EXPECT_EQ(t.set_attributes(rw, 0600u, std::nullopt, 1000u), 0);
  EXPECT_EQ(t.node(rw)->mode, 0600u);
  EXPECT_FALSE(t.node(rw)->uid);
  EXPECT_EQ(t.node(rw)->gid, 1000u);
  EXPECT_EQ(t.set_attributes(link, 0700u, std::nullopt, std::nullopt), EPERM);
  EXPECT_EQ(t.set_attributes(999, 0700u, std::nullopt, std::nullopt), ENOENT);

  EXPECT_TRUE(t.take_notified().empty());
  t.notify(ro);
  t.notify(wo);
  t.notify(ro);
  EXPECT_EQ(t.node(ro)->event, 2u);
  EXPECT_EQ(t.take_notified(), (std::vector<Ino>{ro, wo}));
  EXPECT_TRUE(t.take_notified().empty());
  t.remove(t.resolve("d/m"));
  t.notify(ro);  // a dead node is not notified
  EXPECT_TRUE(t.take_notified().empty());
  EXPECT_EQ(t.set_attributes(rw, 0644u, std::nullopt, std::nullopt), ENODEV);
}

TEST(Tree, KernelIntegerParsing) {
  long long v = 0;
  EXPECT_EQ(parse_kernel_int("42\n", -100, 100, v), 0);
  EXPECT_EQ(v, 42);
  EXPECT_EQ(parse_kernel_int("-7", -100, 100, v), 0);
  EXPECT_EQ(v, -7);
  EXPECT_EQ(parse_kernel_int("+7", -100, 100, v), 0);
  EXPECT_EQ(parse_kernel_int("", -100, 100, v), EINVAL);
  EXPECT_EQ(parse_kernel_int("\n", -100, 100, v), EINVAL);
  EXPECT_EQ(parse_kernel_int(" 4", -100, 100, v), EINVAL);
  EXPECT_EQ(parse_kernel_int("4\n\n", -100, 100, v), EINVAL);
  EXPECT_EQ(parse_kernel_int("0x10", -100, 100, v), EINVAL);
  EXPECT_EQ(parse_kernel_int("101", -100, 100, v), ERANGE);
  EXPECT_EQ(parse_kernel_int("99999999999999999999999", -100, 100, v), ERANGE);
  EXPECT_TRUE(sysfs_streq("hold\n", "hold"));
  EXPECT_TRUE(sysfs_streq("hold", "hold\n"));
  EXPECT_FALSE(sysfs_streq("hold\n\n", "hold"));
  EXPECT_FALSE(sysfs_streq("hol", "hold"));
}

TEST(Geometry, OverlapsAndRays) {
  const Convex square = rect(0, 0, 10, 10);
  EXPECT_TRUE(overlaps(square, rect(5, 5, 15, 15)));
  EXPECT_FALSE(overlaps(square, rect(11, 0, 20, 10)));
  EXPECT_TRUE(overlaps(square, rect(10, 0, 20, 10)));  // touching counts
  EXPECT_TRUE(overlaps(square, Convex{{-5, 5}, {15, 5}}));   // a segment through it
  EXPECT_FALSE(overlaps(square, Convex{{-5, 12}, {15, 12}}));
  EXPECT_FALSE(overlaps(Convex{{0, 0}, {1, 0}}, Convex{{2, 0}, {3, 0}}));  // collinear, apart
  EXPECT_TRUE(overlaps(Convex{{0, 0}, {2, 0}}, Convex{{1, 0}, {3, 0}}));
  EXPECT_FALSE(overlaps(Convex{{0, 0}, {1, 1}}, Convex{{0, 2}, {2, 0.5}}) &&
               !overlaps(Convex{{0, 0}, {1, 1}}, Convex{{0, 1}, {1, 0}}));
  const auto t = ray_segment({0, 0}, {1, 0}, {5, -1}, {5, 1});
  ASSERT_TRUE(t);
  EXPECT_DOUBLE_EQ(*t, 5);
  EXPECT_FALSE(ray_segment({0, 0}, {-1, 0}, {5, -1}, {5, 1}));
  EXPECT_DOUBLE_EQ(*ray_convex({-10, 5}, {1, 0}, square), 10);
  EXPECT_DOUBLE_EQ(*ray_convex({5, 5}, {1, 0}, square), 0);  // inside
  EXPECT_TRUE(point_in_polygon({1, 1}, {{0, 0}, {4, 0}, {0, 4}}));
  EXPECT_FALSE(point_in_polygon({3, 3}, {{0, 0}, {4, 0}, {0, 4}}));
  EXPECT_NEAR(wrap_angle(3 * kPi), kPi, 1e-12);
  EXPECT_NEAR(wrap_angle(-kPi / 2 - 2 * kPi), -kPi / 2, 1e-12);
}

std::string parse(std::vector<const char*> args, SimOptions& o) {
  args.insert(args.begin(), "ev3-sim");
  return parse_sim_options(static_cast<int>(args.size()), args.data(), o);
}

TEST(Options, SeveralRobotsAndErrors) {
  SimOptions o;
  ASSERT_EQ(parse({"--world", "w.txt", "--sysfs-root", "/tmp/a", "--robot", "10,20,90", "--sysfs-root", "/tmp/b",
                   "--name", "alice", "--name", "bob", "--time-scale", "10", "--jessie"},
                  o),
            "");
  ASSERT_EQ(o.robots.size(), 2u);
  EXPECT_EQ(o.robots[0].name, "alice");
  EXPECT_EQ(o.robots[1].name, "bob");
  ASSERT_TRUE(o.robots[0].pose);
  EXPECT_DOUBLE_EQ(o.robots[0].pose->p.y, 20);
  EXPECT_NEAR(o.robots[0].pose->heading, kPi / 2, 1e-12);
  EXPECT_FALSE(o.robots[1].pose);
  EXPECT_EQ(o.gen, Generation::Jessie);
  EXPECT_DOUBLE_EQ(o.time_scale, 10);

  SimOptions e;
  EXPECT_EQ(parse({"--sysfs-root", "/tmp/a"}, e), "missing --world FILE");
  EXPECT_EQ(parse({"--world", "w"}, e), "missing --sysfs-root DIR (where the robot's tree is mounted)");
  EXPECT_EQ(parse({"--world", "w", "--sysfs-root", "a", "--robot", "1,2"}, e),
            "bad value for --robot: '1,2' (expected X,Y,HEADING in cm, cm, degrees, e.g. 30,40,90)");
  EXPECT_EQ(parse({"--world", "w", "--sysfs-root", "a", "--robot", "1,2,3", "--robot", "4,5,6"}, e),
            "more --robot than --sysfs-root (one --robot per robot)");
  EXPECT_EQ(parse({"--world", "w", "--sysfs-root", "a", "--sysfs-root", "a"}, e), "two robots share --sysfs-root a");
  EXPECT_EQ(parse({"--world", "w", "--sysfs-root", "a", "--rate", "50"}, e),
            "bad value for --rate: '50' (expected a rate of 100..10000 Hz)");
  EXPECT_EQ(parse({"--world", "w", "--sysfs-root", "a", "--time-scale", "0"}, e),
            "bad value for --time-scale: '0' (expected a factor 0.01..1000)");
  EXPECT_EQ(parse({"--world", "w", "--sysfs-root", "a", "--bogus"}, e), "unknown flag '--bogus'");
}

std::string parse_exec(std::vector<const char*> args, ExecOptions& o) {
  args.insert(args.begin(), "exec");
  return parse_exec_options(static_cast<int>(args.size()), args.data(), o);
}

TEST(Options, ExecArgumentsAndErrors) {
  ExecOptions o;
  ASSERT_EQ(parse_exec({"--robot", "2", "--", "python3", "--robot", "x"}, o), "");
  EXPECT_EQ(o.robot, "2");
  EXPECT_EQ(o.command, (std::vector<std::string>{"python3", "--robot", "x"}));
  ExecOptions e;
  EXPECT_EQ(parse_exec({"--", "true"}, e), "exec: name the robot: --robot N|NAME or --sysfs-root DIR");
  ExecOptions e2;
  EXPECT_EQ(parse_exec({"--robot", "1"}, e2), "exec: no command (give it after --)");
  ExecOptions e3;
  EXPECT_EQ(parse_exec({"--robot"}, e3), "exec: --robot needs a value");
  ExecOptions e4;
  EXPECT_EQ(parse_exec({"--robot", "1", "true"}, e4), "exec: unknown argument 'true' (the command comes after --)");
  ExecOptions e5;
  EXPECT_EQ(parse_exec({"--robot", "1", "--robot", "2", "--", "true"}, e5), "exec: --robot given twice");
}

TEST(Options, ExecFindsTheRobotsTreeInMountinfo) {
  const std::string info =
      "22 1 0:21 / /sys rw,nosuid - sysfs sysfs rw\n"
      "44 27 0:40 / /tmp/r1 rw,nosuid,nodev,relatime - fuse.ev3-sim ev3-sim:1:robot1 rw,user_id=0\n"
      "45 27 0:41 / /tmp/my\\040dir rw shared:7 - fuse.ev3-sim ev3-sim:2:bob rw,user_id=0\n"
      "46 27 0:42 / /tmp/old rw - fuse.ev3-sim ev3-sim rw,user_id=0\n"
      "47 27 0:43 / /tmp/s2 rw - fuse.ev3-sim ev3-sim:1:robot1 rw,user_id=0\n";
  EXPECT_EQ(mount_source(2, "bob"), "ev3-sim:2:bob");
  const std::vector<SimMount> all = parse_sim_mounts(info);
  ASSERT_EQ(all.size(), 3u);  // the old source without a robot is not one
  EXPECT_EQ(all[1].dir, "/tmp/my dir");
  EXPECT_EQ(all[1].index, 2);
  EXPECT_EQ(all[1].name, "bob");

  SimMount m;
  // pick(--robot, --sysfs-root): the error, "" when found (then m).
  auto pick = [&](const std::vector<SimMount>& mounts, const char* robot, const char* root) {
    ExecOptions o;
    o.robot = robot;
    o.root = root;
    return pick_sim_mount(mounts, o, root, m);
  };
  EXPECT_EQ(pick(all, "2", ""), "");
  EXPECT_EQ(m.dir, "/tmp/my dir");
  EXPECT_EQ(pick(all, "robot1", ""),
            "exec: robot robot1 is ambiguous: robot1 (robot 1) on /tmp/r1, robot1 (robot 1) on /tmp/s2; name its "
            "tree with --sysfs-root DIR");
  EXPECT_EQ(pick(all, "", "/tmp/s2"), "");
  EXPECT_EQ(m.dir, "/tmp/s2");
  EXPECT_EQ(pick(all, "7", ""),
            "exec: no running ev3-sim serves robot 7 (running: robot1 (robot 1) on /tmp/r1, bob (robot 2) on /tmp/my "
            "dir, robot1 (robot 1) on /tmp/s2)");
  EXPECT_EQ(pick(all, "bob", "/tmp").rfind("exec: no running ev3-sim serves a tree on /tmp for robot bob", 0), 0u);
  EXPECT_EQ(pick({}, "2", ""), "exec: no ev3-sim is running (no fuse.ev3-sim mount in /proc/self/mountinfo)");
}

}  // namespace
