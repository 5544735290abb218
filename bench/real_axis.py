#!/usr/bin/env python3
"""`beamtool diagnose` on a real linear axis: the LinA and LinB actuators of
github.com/nicolazande/camber-control (commit cb9a8f8; no licence stated, so the logs are read
from your own clone by path and never copied into this project).

Usage (from the repository root; standard library only):
    git clone https://github.com/nicolazande/camber-control /tmp/camber-control
    python3 bench/real_axis.py tools/target/*/release/beamtool /tmp/camber-control [--out DIR]

Each log is tab-separated: time (ms), target position (mm), position demand (mm, the path
planner's output: the position loop's command), actual position (mm, 10 um counts), actual
speed, motor current (LinA mA, LinB A). The rod's force is the current times the motor's torque
constant times the motor radians per metre of rod (`Kt * grtot` of the source's
model_setup.m); the carriage mass of the rig file is the rotor's inertia reflected to the rod
(`Jm * grtot^2`). The rig has no beam: a carriage-only rig, whose catalogue is the loop,
friction and cogging.

Runs (fit, fit, validate):
  LinA  the path-planned sine sweep cut in two halves and the path-planned square wave, in each
        of the three roles (100 Hz logs)
  LinB  square waves full travel 0.5 Hz, half travel 2 Hz, full travel 1 Hz (a PC polling the
        drive every 12-21 ms)
One line per run: exit status, named effects with their main parameters, unexplained channel and
band, run time.
"""
import argparse
import json
import math
import os
import subprocess
import sys
import time

AXES = {
    # Kt (N m/A), motor radians per metre of rod, rotor + gearhead inertia (kg m^2), current unit (A)
    'LinA': (42.9e-3, 1000 * 2 * math.pi * 85.58 / 24, 1.55e-6 + 8e-8, 1e-3),
    'LinB': (72.8e-3, 1000 * 2 * math.pi * 174.72 / 48, 7.8e-6 + 1.4e-6, 1.0),
}

RIG = """# {axis} of github.com/nicolazande/camber-control (commit cb9a8f8), written by bench/real_axis.py:
# Kt {kt} N m/A, {grtot:.0f} motor radians per metre of rod: {fpa:.0f} N per A on the rod; the rotor's
# inertia reflected to the rod {mass:.0f} kg. No beam: a carriage-only rig.
[base]
mass_kg = {mass:.1f}

[sensors]
sample_rate_hz = {rate}
"""


def convert(src, dst, axis, rows=None):
    """Log `src` -> recording CSV `dst` (SI units, the command = the position demand)."""
    kt, grtot, _, amp = AXES[axis]
    lines = [l.split() for l in open(src) if len(l.split()) >= 6]
    if rows is not None:
        lines = lines[rows[0]:rows[1]]
    with open(dst, 'w') as g:
        g.write('time_s,base_cmd_m,base_pos_m,force_n\n')
        for c in lines:
            g.write('%.3f,%.6e,%.6e,%.6e\n' % (float(c[0]) / 1e3, float(c[2]) / 1e3, float(c[3]) / 1e3,
                                               float(c[5]) * amp * kt * grtot))
    return len(lines)


def write_rig(path, axis, rate):
    kt, grtot, j, _ = AXES[axis]
    with open(path, 'w') as f:
        f.write(RIG.format(axis=axis, kt=kt, grtot=grtot, fpa=kt * grtot, mass=j * grtot ** 2, rate=rate))


def run(tool, d, fit, val):
    t0 = time.time()
    p = subprocess.run([tool, 'diagnose', '--rig', 'rig.toml', '--fit', fit[0], '--fit', fit[1], '--validate', val,
                        '--json', 'out.json'], cwd=d, capture_output=True, text=True)
    dt = time.time() - t0
    if p.returncode != 0:
        return '%s | %s | rc=%d %s (%.1f s)' % ('+'.join(fit), val, p.returncode, p.stderr.strip().splitlines()[-1],
                                                 dt)
    o = json.load(open(os.path.join(d, 'out.json')))
    named = []
    for e in o.get('effects', []):
        ps = e.get('parameters', {})
        us = e.get('uncertainty', {})
        keys = [k for k in ('servo_bandwidth_hz', 'servo_following_error_rms_m', 'friction_n', 'viscous_n_s_per_m')
                if k in ps]
        named.append('%s(%s)' % (e['effect'], ', '.join(
            '%s %.4g%s' % (k, ps[k], (' ± %.2g' % us[k]) if isinstance(us.get(k), (int, float)) else '')
            for k in keys)))
    u = o.get('unexplained') or {}
    unexpl = ('%s %.2f-%.2f Hz' % (u['channel'], *u['band_hz'])) if u else 'none'
    return '%s | %s | rc=0 named %s; unexplained %s (%.1f s)' % ('+'.join(fit), val, ' + '.join(named) or 'none',
                                                                 unexpl, dt)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('tool')
    ap.add_argument('clone', help='a clone of github.com/nicolazande/camber-control')
    ap.add_argument('--out', default='/tmp/real-axis')
    a = ap.parse_args()
    tool = os.path.abspath(a.tool)
    data = lambda axis, name: os.path.join(a.clone, 'actuators', axis, 'data', name + '.txt')
    d = os.path.join(a.out, 'LinA')
    os.makedirs(d, exist_ok=True)
    write_rig(os.path.join(d, 'rig.toml'), 'LinA', 100.0)
    n = convert(data('LinA', 'pp-sine-sweep-10mm-0.5Hz'), os.devnull, 'LinA')
    convert(data('LinA', 'pp-sine-sweep-10mm-0.5Hz'), os.path.join(d, 'sweep-a.csv'), 'LinA', (0, n // 2))
    convert(data('LinA', 'pp-sine-sweep-10mm-0.5Hz'), os.path.join(d, 'sweep-b.csv'), 'LinA', (n // 2, n))
    convert(data('LinA', 'pp-square-wave-10mm-0.5Hz'), os.path.join(d, 'square.csv'), 'LinA')
    for fit, val in [(('sweep-a.csv', 'square.csv'), 'sweep-b.csv'), (('sweep-b.csv', 'square.csv'), 'sweep-a.csv'),
                     (('sweep-a.csv', 'sweep-b.csv'), 'square.csv')]:
        print('LinA', run(tool, d, fit, val), flush=True)
    d = os.path.join(a.out, 'LinB')
    os.makedirs(d, exist_ok=True)
    write_rig(os.path.join(d, 'rig.toml'), 'LinB', 70.0)
    names = ['full-travel-0.5Hz', 'half-travel-2Hz', 'full-travel-1Hz']
    for name in names:
        convert(data('LinB', 'no-load-square-wave-' + name), os.path.join(d, name + '.csv'), 'LinB')
    print('LinB', run(tool, d, (names[0] + '.csv', names[1] + '.csv'), names[2] + '.csv'), flush=True)


if __name__ == '__main__':
    sys.exit(main())
