"""A brick's program in python-ev3dev2, as it would run on an EV3 with model A: nothing in it knows
about the simulator (tests/python/blackbox/test_ev3dev2.py runs it through `ev3-sim exec`).

Drives two wheel turns forward, reads the floor's colour and the distance ahead, turns right on
the spot, drives until the bumper's touch sensor is pressed, and sets the LEDs on the way. After
each of the three moves it prints what it read as one JSON line and waits for a line on its
standard input before it goes on (the test looks at the robot meanwhile)."""

import json
import sys

from ev3dev2 import get_current_platform
from ev3dev2.led import Leds
from ev3dev2.motor import OUTPUT_A, OUTPUT_B, OUTPUT_C, MoveTank
from ev3dev2.port import LegoPort
from ev3dev2.sensor import INPUT_1, INPUT_2, INPUT_3, INPUT_4
from ev3dev2.sensor.lego import ColorSensor, TouchSensor, UltrasonicSensor

tank = MoveTank(OUTPUT_B, OUTPUT_C)
colour = ColorSensor(INPUT_3)
sonar = UltrasonicSensor(INPUT_4)
touch = TouchSensor(INPUT_1)
leds = Leds()


def report(step, readings):
    print(json.dumps(dict(readings, step=step)), flush=True)
    sys.stdin.readline()


readings = {"platform": get_current_platform()}
# What each port found (the lego-port class): the touch sensor is analog, the others UART.
readings["ports"] = {p: [LegoPort(p).mode, LegoPort(p).status]
                     for p in (INPUT_1, INPUT_2, INPUT_3, OUTPUT_A, OUTPUT_B)}
# Put the sensors in their modes before the values matter: a mode change takes a few tens of
# milliseconds and the first values after it are stale.
readings["colour_at_start"] = colour.color_name
readings["distance_at_start"] = sonar.distance_centimeters
leds.set_color("LEFT", "AMBER")
leds.set_color("RIGHT", "AMBER")

tank.on_for_rotations(50, 50, 2)
readings["colour"] = colour.color_name
readings["distance"] = sonar.distance_centimeters
report("drive", readings)

# A quarter turn to the right on the spot: each wheel turns 90 deg x (wheel base / wheel diameter)
# = 90 x 120 / 56 = 193 degrees.
tank.on_for_degrees(20, -20, 193)
report("turn", {})

tank.on(30, 30)
readings["pressed_in_time"] = touch.wait_for_pressed(timeout_ms=10000)
tank.off()
readings["pressed"] = touch.is_pressed

leds.set_color("LEFT", "RED")
leds.set_color("RIGHT", "GREEN")
report("touch", readings)
