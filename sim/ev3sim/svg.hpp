/// @file svg.hpp
/// @brief A picture of the simulation as SVG text: the world (bounds, floor patches, boxes,
///        walls), each robot's path so far, its body coloured by its LEDs, its heading, the
///        ultrasonic's ray and a pressed bumper.
#pragma once

#include <string>

#include "ev3sim/sim.hpp"

namespace ev3sim {

/// The SVG document (1 cm = 4 px, y pointing up as in the world file).
std::string snapshot_svg(const Sim& sim);

}  // namespace ev3sim
