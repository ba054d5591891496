#include "ev3sim/sim.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>

#include <ev3proto/json.hpp>

namespace ev3sim {

namespace {

bool to_number(const std::string& s, double& out) {
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  if (s.empty() || *end != '\0' || !std::isfinite(v)) return false;
  out = v;
  return true;
}

std::string fixed(double v, int decimals) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

}  // namespace

bool parse_pose(std::string_view s, Pose& out) {
  std::string text(s);
  double v[3];
  std::size_t start = 0;
  for (int i = 0; i < 3; ++i) {
    const std::size_t comma = text.find(',', start);
    if ((i < 2) != (comma != std::string::npos)) return false;
    if (!to_number(text.substr(start, comma == std::string::npos ? std::string::npos : comma - start), v[i]))
      return false;
    start = comma + 1;
  }
  out.p = {v[0], v[1]};
  out.heading = wrap_angle(deg2rad(v[2]));
  return true;
}

Sim::Sim(World world) : world_(std::move(world)), walls_(world_.all_walls()) {}

Robot* Sim::robot(std::string_view name) {
  for (auto& r : robots_)
    if (r->name() == name) return r.get();
  return nullptr;
}

bool Sim::blocked(const Convex& shape, const Robot* except) const {
  for (Vec2 v : shape)
    if (v.x < world_.x0 || v.x > world_.x1 || v.y < world_.y0 || v.y > world_.y1) return true;
  for (const Segment& w : walls_)
    if (overlaps(shape, Convex{w.a, w.b})) return true;
  for (const Box& b : world_.boxes)
    if (overlaps(shape, b.shape)) return true;
  for (const auto& r : robots_)
    if (r.get() != except && overlaps(shape, r->footprint())) return true;
  return false;
}

std::string Sim::add_robot(RobotConfig cfg) {
  if (robot(cfg.name)) return "two robots are called " + cfg.name;
  const Vec2 p = cfg.start.p;
  auto r = std::make_unique<Robot>(std::move(cfg));
  if (blocked(r->footprint(), nullptr))
    return "robot " + r->name() + " at (" + fixed(p.x, 1) + ", " + fixed(p.y, 1) +
           ") overlaps a wall, a box or another robot, or leaves the bounds";
  r->set_now(now_);
  robots_.push_back(std::move(r));
  sense_all();  // the new robot's sensors have values from the start
  return {};
}

double Sim::ultrasonic_distance(const Robot& r) const {
  const Vec2 o = r.ultrasonic_origin();
  const Vec2 dir{std::cos(r.pose().heading), std::sin(r.pose().heading)};
  double best = -1;
  auto consider = [&best](std::optional<double> t) {
    if (t && (best < 0 || *t < best)) best = *t;
  };
  for (const Segment& w : walls_) consider(ray_segment(o, dir, w.a, w.b));
  for (const Box& b : world_.boxes) consider(ray_convex(o, dir, b.shape));
  for (const auto& other : robots_)
    if (other.get() != &r) consider(ray_convex(o, dir, other->footprint()));
  return best > kUltrasonicRangeCm ? -1 : best;
}

void Sim::step() {
  now_ += kStepUs;
  const double dt = kStepUs / 1e6;
  for (auto& r : robots_) {
    r->set_now(now_);
    r->propose(dt, now_);
  }
  // Bodies move one after the other; one that would overlap something stops at contact.
  for (auto& r : robots_) {
    Robot& rob = *r;
    Pose from = rob.pose();
    Pose to = rob.propose_target();
    if (!blocked(rob.footprint(to), &rob)) {
      rob.commit(1.0, false, now_, dt);
      continue;
    }
    double lo = 0, hi = 1;
    for (int i = 0; i < 8; ++i) {
      const double mid = (lo + hi) / 2;
      Pose p;
      p.p = from.p + (to.p - from.p) * mid;
      p.heading = from.heading + wrap_angle(to.heading - from.heading) * mid;
      (blocked(rob.footprint(p), &rob) ? hi : lo) = mid;
    }
    rob.commit(lo, true, now_, dt);
  }
  sense_all();
}

void Sim::sense_all() {
  for (auto& r : robots_) r->set_bumper(blocked(r->bumper_zone(), r.get()));
  for (auto& r : robots_) {
    Perception p;
    p.distance_cm = ultrasonic_distance(*r);
    for (const auto& other : robots_)
      if (other.get() != r.get() && other->ultrasonic_emitting() &&
          length(other->ultrasonic_origin() - r->ultrasonic_origin()) <= kUltrasonicRangeCm)
        p.heard = true;
    world_.floor_at(r->colour_spot(), p.colour, p.reflect);
    r->sense(now_, p);
  }
}

void Sim::advance_to(SimTime t) {
  while (now_ + kStepUs <= t) step();
}

ControlResult Sim::control(std::string_view line) {
  const auto w = split_words(line);
  ControlResult res;
  auto fail = [&res](std::string m) {
    res.ok = false;
    res.message = std::move(m);
    return res;
  };
  if (w.empty()) return fail("empty command");
  const std::string& cmd = w[0];
  if (cmd == "quit") {
    res.action = ControlAction::Quit;
    res.message = "quitting";
    return res;
  }
  if (cmd == "snapshot" || cmd == "status") {
    if (w.size() > 2) return fail(cmd + " takes at most a file name");
    res.action = cmd == "snapshot" ? ControlAction::Snapshot : ControlAction::Status;
    res.path = w.size() == 2 ? w[1] : "";
    res.message = cmd;
    return res;
  }
  struct Spec {
    const char* name;
    std::size_t args;  // after the robot
    const char* usage;
  };
  static const Spec kSpecs[] = {
      {"unplug", 1, "unplug [ROBOT] PORT"},         {"replug", 1, "replug [ROBOT] PORT"},
      {"plug", 2, "plug [ROBOT] PORT DRIVER"},      {"battery", 1, "battery [ROBOT] VOLTS"},
      {"garbage", 2, "garbage [ROBOT] PORT on|off"}, {"place", 3, "place [ROBOT] X Y HEADING"},
  };
  const Spec* spec = nullptr;
  for (const Spec& s : kSpecs)
    if (cmd == s.name) spec = &s;
  if (!spec)
    return fail("unknown command '" + cmd + "' (unplug, replug, plug, battery, garbage, place, snapshot, status, quit)");
  Robot* r = nullptr;
  std::size_t first = 1;
  if (w.size() == spec->args + 2) {
    r = robot(w[1]);
    if (!r) return fail("no robot called '" + w[1] + "'");
    first = 2;
  } else if (w.size() == spec->args + 1) {
    if (robots_.size() != 1) return fail(std::string("say which robot: ") + spec->usage);
    r = robots_.front().get();
  } else {
    return fail(std::string("usage: ") + spec->usage);
  }
  const std::vector<std::string> a(w.begin() + static_cast<std::ptrdiff_t>(first), w.end());
  std::string err;
  r->set_now(now_);
  if (cmd == "unplug") err = r->unplug(a[0]);
  else if (cmd == "replug") err = r->replug(a[0]);
  else if (cmd == "plug") err = r->plug(a[0], a[1]);
  else if (cmd == "battery") {
    double v;
    if (!to_number(a[0], v) || v < 0 || v > 12) return fail("battery needs a voltage 0..12, got '" + a[0] + "'");
    r->set_battery_volts(v);
  } else if (cmd == "garbage") {
    Sensor* s = r->sensor(a[0]);
    if (!s) return fail("no sensor in " + r->name() + "'s port " + a[0]);
    if (a[1] != "on" && a[1] != "off") return fail("garbage takes on or off, got '" + a[1] + "'");
    s->set_garbage(a[1] == "on");
  } else if (cmd == "place") {
    double x, y, h;
    if (!to_number(a[0], x) || !to_number(a[1], y) || !to_number(a[2], h)) return fail("place needs X Y HEADING numbers");
    Pose p;
    p.p = {x, y};
    p.heading = wrap_angle(deg2rad(h));
    if (blocked(r->footprint(p), r)) return fail("robot " + r->name() + " would overlap something there or leave the bounds");
    r->set_pose(p);
  }
  if (!err.empty()) return fail(r->name() + ": " + err);
  res.message = r->name() + ": " + std::string(line.substr(0, line.find('\n')));
  return res;
}

std::string Sim::status_json() const {
  std::string s = "{\"time\": " + fixed(static_cast<double>(now_) / 1e6, 3) + ", \"robots\": [";
  bool first_robot = true;
  for (const auto& rp : robots_) {
    Robot& r = *rp;
    s += first_robot ? "\n" : ",\n";
    first_robot = false;
    double heading = std::fmod(rad2deg(r.pose().heading) + 360.0, 360.0);
    s += "  {\"name\": " + ev3proto::json_quote(r.name()) + ", \"x\": " + fixed(r.pose().p.x, 2) +
         ", \"y\": " + fixed(r.pose().p.y, 2) + ", \"heading\": " + fixed(heading, 2) +
         ", \"heading_total\": " + fixed(r.heading_total(), 2) + ", \"speed\": " + fixed(r.speed(), 2) +
         ", \"bumper\": " + (r.bumper() ? "true" : "false") + ", \"bumper_pressed_at\": " +
         (r.bumper_pressed_at() < 0 ? std::string("null") : fixed(static_cast<double>(r.bumper_pressed_at()) / 1e6, 4)) +
         ", \"travelled\": " + fixed(r.distance_travelled(), 2) +
         ", \"battery\": {\"volts\": " + fixed(r.volts(), 4) + ", \"amps\": " + fixed(r.amps(), 4) + "}";
    s += ", \"ports\": {";
    bool first = true;
    for (const char* port : {"in1", "in2", "in3", "in4", "outA", "outB", "outC", "outD"}) {
      const std::string driver = r.plugged(port);
      if (driver.empty()) continue;
      s += std::string(first ? "" : ", ") + ev3proto::json_quote(port) + ": {\"driver\": " + ev3proto::json_quote(driver) +
           ", \"class\": " + ev3proto::json_quote(r.class_path(port));
      first = false;
      if (TachoMotor* m = r.motor(port)) {
        s += ", \"position\": " + std::to_string(m->position()) + ", \"speed\": " + fixed(m->speed(), 1) +
             ", \"state\": " + ev3proto::json_quote(m->state());
      } else if (Sensor* se = r.sensor(port)) {
        s += ", \"mode\": " + ev3proto::json_quote(se->mode().name) + ", \"values\": [";
        for (int i = 0; i < se->mode().num_values; ++i) s += (i ? ", " : "") + std::to_string(se->value(i));
        s += std::string("], \"garbage\": ") + (se->garbage() ? "true" : "false") +
             ", \"locked\": " + (se->locked(now_) ? "true" : "false");
      }
      s += "}";
    }
    s += "}, \"leds\": {";
    first = true;
    for (const Led& l : r.leds()) {
      s += std::string(first ? "" : ", ") + ev3proto::json_quote(l.name) + ": {\"brightness\": " + std::to_string(l.brightness) +
           ", \"trigger\": " + ev3proto::json_quote(l.trigger) + ", \"delay_on\": " + std::to_string(l.delay_on) +
           ", \"delay_off\": " + std::to_string(l.delay_off) + "}";
      first = false;
    }
    s += "}}";
  }
  return s + "\n]}\n";
}

}  // namespace ev3sim
