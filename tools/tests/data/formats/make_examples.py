#!/usr/bin/env python3
"""Writes the small example files of docs/recording-formats.md (deterministic; plain python3).

Run from this directory: python3 make_examples.py
"""
import math
import random

random.seed(70)
TAU = 2 * math.pi

# Klipper raw accelerometer CSV: `#time,accel_x,accel_y,accel_z`, time in s (printer clock),
# mm/s^2 in multiples of the ADXL345 LSB (3.9 mg), ~3.2 kHz with jittering stamps.
LSB = 0.0039 * 9806.65
with open("klipper_raw.csv", "w") as f:
    f.write("#time,accel_x,accel_y,accel_z\n")
    for k in range(120):
        t = 1234.5 + k / 3200.0 + random.uniform(-2e-6, 2e-6)
        ax = round(random.gauss(0, 60) / LSB) * LSB
        ay = round((2500 * math.sin(TAU * 95.0 * t) + random.gauss(0, 60)) / LSB) * LSB
        az = round((9806.65 + random.gauss(0, 60)) / LSB) * LSB
        f.write("%.6f,%.6f,%.6f,%.6f\n" % (t, ax, ay, az))

# A ROS bag exported row-wise: one row per message, `%time` in ns; the trolley topic
# (position in mm) at 50 Hz, the sway angle topic (rad, 0.001 rad steps) at ~22 Hz.
rows = []
for k in range(100):
    t = 0.02 * k + 0.0013
    rows.append((t, "%.1f" % (400.0 * (1 - math.cos(TAU * 0.25 * t))), ""))
for k in range(44):
    t = k / 22.0 + 0.0071
    rows.append((t, "", "%.3f" % (0.08 * math.sin(TAU * 0.735 * t))))
rows.sort()
with open("rowwise_ros.csv", "w") as f:
    f.write("%time,field.trolley_mm,field.sway_rad\n")
    for t, pos, ang in rows:
        f.write("%d,%s,%s\n" % (round(1.7e18 + t * 1e9), pos, ang))

# A staircase: a 100 Hz log whose tip camera updates at 22 Hz (each value repeated until the
# next frame); the base encoder at the full rate.
with open("staircase.csv", "w") as f:
    f.write("time_s,base_pos_m,tip_pos_m\n")
    for k in range(200):
        t = k / 100.0
        held = math.floor(t * 22.0) / 22.0
        base = 0.05 * math.sin(TAU * 0.5 * t)
        tip = 0.05 * math.sin(TAU * 0.5 * held) + 0.004 * math.sin(TAU * 3.0 * held)
        f.write("%.2f,%.7f,%.7f\n" % (t, base, tip))

# Columns to map with --columns: time in ms, hub angle in rad, tip deflection in whole mm
# (a 1 mm-quantised swing, not a staircase), and a text column that is never read.
with open("scaled_columns.csv", "w") as f:
    f.write("t,theta,defl,status\n")
    for k in range(200):
        t = k * 1.0
        theta = 0.1 * math.sin(TAU * 0.5 * t / 1000.0)
        defl = round(20.0 * math.sin(TAU * 1.75 * t / 1000.0 + 0.3))
        f.write("%g,%.6f,%d,%s\n" % (t, theta, defl, "run" if k % 50 else "step"))
