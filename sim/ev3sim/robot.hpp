/// @file robot.hpp
/// @brief One simulated brick and its body: the ev3dev tree (stretch or jessie names) with the
///        devices plugged into its ports, the LEDs and the battery, and model A's differential-
///        drive body (wheel diameter, wheel base, footprint, where the sensors sit).
///
/// The Robot serves its tree (tree()); writes reach the device emulations at once and act at the
/// next simulation step. Devices are plugged and unplugged by port; every plug gets the next
/// motorN/sensorN index, as on a brick.
#pragma once

#include <array>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "ev3sim/drivers.hpp"
#include "ev3sim/geometry.hpp"
#include "ev3sim/motor.hpp"
#include "ev3sim/sensor.hpp"
#include "ev3sim/tree.hpp"

namespace ev3sim {

/// Model A, the thesis' test robot (docs/devices.md, "Model A"). Lengths in cm, body frame:
/// x forward from the midpoint of the wheel axle, y to the left.
struct ModelA {
  double wheel_diameter = 5.6;  ///< EV3 education set tyre 56 x 28 mm
  double wheel_base = 12.0;     ///< axle track, tyre centre to tyre centre (about 120 mm)
  double body_front = 12.0;     ///< the front bumper's face
  double body_rear = -6.0;
  double body_half_width = 7.5;
  double bumper_travel = 0.6;   ///< how close an obstacle presses the bumper
  double bumper_half_width = 6.0;
  Vec2 ultrasonic{11.0, 0.0};   ///< facing forward
  Vec2 colour{8.0, 0.0};        ///< facing the floor
  double traction = 0.7;        ///< tyre-floor friction coefficient: the body's deceleration limit
  std::string left = "outB", right = "outC", touch = "in1", colour_port = "in3", ultrasonic_port = "in4";
};

/// The battery model (docs/devices.md, "Battery").
struct BatteryModel {
  double full_volts = 8.04;    ///< open-circuit voltage at start (7.99 V read at idle)
  double empty_volts = 6.0;    ///< open-circuit voltage when the capacity is used up
  double capacity_mah = 2000;  ///< 6 AA cells
  double resistance = 0.3;     ///< internal resistance (ohm): the voltage sags under load
  double idle_amps = 0.16;     ///< the brick itself
};

struct RobotConfig {
  std::string name = "robot1";
  Generation gen = Generation::Stretch;
  Pose start;
  ModelA model;
  BatteryModel battery;
  std::uint64_t seed = 1;
};

/// One of the brick's LEDs (leds class): brightness, trigger, timer blinking.
struct Led {
  std::string name;
  int brightness = 0;        ///< the brightness set (the "on" level while blinking)
  std::string trigger = "none";
  int delay_on = 500, delay_off = 500;
  SimTime trigger_since = 0;
  /// What `brightness` reads at @p now (0 in the off phase of a timer blink).
  int shown(SimTime now) const;
};

class Robot {
 public:
  explicit Robot(RobotConfig cfg);
  Robot(const Robot&) = delete;
  Robot& operator=(const Robot&) = delete;

  const std::string& name() const { return cfg_.name; }
  const RobotConfig& config() const { return cfg_; }
  Tree& tree() { return tree_; }
  const Tree& tree() const { return tree_; }

  /// The simulated time writes are stamped with (the Sim sets it before serving I/O).
  void set_now(SimTime now) { now_ = now; }

  // --- devices ----------------------------------------------------------------------------
  /// Plugs @p driver into @p port (outA..outD, in1..in4). "" or an error.
  std::string plug(const std::string& port, const std::string& driver);
  /// Unplugs whatever is in @p port. "" or an error.
  std::string unplug(const std::string& port);
  /// Plugs back the device last unplugged from @p port. "" or an error.
  std::string replug(const std::string& port);
  /// Driver name in @p port, or "".
  std::string plugged(const std::string& port) const;
  TachoMotor* motor(const std::string& port);
  Sensor* sensor(const std::string& port);
  /// The class directory of the device in @p port ("class/tacho-motor/motor3"), or "".
  std::string class_path(const std::string& port) const;
  const std::array<Led, 4>& leds() const { return leds_; }

  // --- battery ----------------------------------------------------------------------------
  double volts() const { return volts_; }
  double amps() const { return amps_; }
  /// Fault: the open-circuit voltage drops to @p v now (and drains on from there).
  void set_battery_volts(double v);

  // --- body -------------------------------------------------------------------------------
  const Pose& pose() const { return pose_; }
  void set_pose(const Pose& p);
  double heading_total() const { return heading_total_; }
  double speed() const { return v_; }
  bool bumper() const { return bumper_; }
  void set_bumper(bool pressed) {
    if (pressed && !bumper_) pressed_at_ = now_;
    bumper_ = pressed;
  }
  /// When the bumper was last pressed (its edge), -1 before the first press.
  SimTime bumper_pressed_at() const { return pressed_at_; }
  const std::vector<Vec2>& path() const { return path_; }
  double distance_travelled() const { return travelled_; }
  /// The footprint at pose @p p.
  Convex footprint(const Pose& p) const;
  Convex footprint() const { return footprint(pose_); }
  /// The thin slab in front of the bumper (pressed when it meets an obstacle).
  Convex bumper_zone() const;
  Vec2 ultrasonic_origin() const { return pose_.to_world(cfg_.model.ultrasonic); }
  Vec2 colour_spot() const { return pose_.to_world(cfg_.model.colour); }
  /// True when an ultrasonic is plugged and measuring (not listening): other robots hear it.
  bool ultrasonic_emitting() const;

  // --- stepping (called by Sim) -----------------------------------------------------------
  /// Controllers of every motor for @p dt seconds; returns the candidate pose the wheels lead
  /// to (the body's velocity limited by traction).
  Pose propose(double dt, SimTime now);
  /// The pose the last propose() led to.
  const Pose& propose_target() const { return candidate_; }
  /// Moves the body by @p fraction (0..1) of the proposed step; @p blocked when an obstacle
  /// stopped it short.
  void commit(double fraction, bool blocked, SimTime now, double dt);
  /// Samples the sensors with what the robot perceives now.
  void sense(SimTime now, const Perception& base);

 private:
  struct Device {
    std::string port;
    std::string driver;
    std::string dir;        // the device directory (devices/...)
    std::string class_dir;  // the class-device directory (devices/.../tacho-motor/motorN)
    std::string class_link; // class/tacho-motor/motorN
    std::unique_ptr<TachoMotor> motor;
    std::unique_ptr<Sensor> sensor;
    Ino state = 0;           // motors: the `state` attribute (notified when it changes)
    std::string last_state;  // what `state` read when last compared
  };
  void build_static_tree();
  void add_common(const std::string& dir, const std::string& subsystem_class, const std::string& device_dir,
                  std::function<std::string()> uevent);
  void add_device_files(Device& d);
  ReadResult read_attr(const std::string& port, const std::string& name);
  WriteResult write_attr(const std::string& port, const std::string& name, std::string_view data);
  void add_led(int i);
  void add_board_info();
  void add_lego_ports();
  /// sysfs_notify on each motor's `state` that differs from what it was at the last call (the
  /// tacho-motor class notifies every change of state).
  void notify_state_changes();
  void set_led_trigger(int i, const std::string& trigger);
  std::string address(const std::string& port) const;
  Device* device(const std::string& port);

  RobotConfig cfg_;
  Tree tree_;
  SimTime now_ = 0;
  SimTime pressed_at_ = -1;
  std::map<std::string, Device> devices_;
  std::map<std::string, std::string> last_driver_;  // per port, for replug
  int next_motor_ = 0;
  int next_sensor_ = 0;
  std::uint64_t plugs_ = 0;
  std::array<Led, 4> leds_;
  std::array<std::string, 4> led_dirs_;

  double used_ah_ = 0;
  double volts_ = 0;
  double amps_ = 0;
  double full_volts_ = 0;

  Pose pose_;
  double heading_total_ = 0;
  double v_ = 0, w_ = 0;  // body velocity (cm/s, rad/s)
  double dl_ = 0, dr_ = 0; // wheel turns proposed this step (user counts)
  Pose candidate_;
  bool bumper_ = false;
  std::vector<Vec2> path_;
  double travelled_ = 0;
};

/// "outB" -> 5, "in1" -> 0 (the lego-port numbering); -1 when not a port.
int port_index(const std::string& port);

}  // namespace ev3sim
