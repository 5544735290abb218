#!/usr/bin/env python3
"""`beamtool diagnose` on imperfect copies of recordings this project did not make.

Usage (from the repository root; standard library only):
    python3 bench/imperfect.py tools/target/*/release/beamtool \
        [--set ../shared/data/independent/discrepancy-v1.tar.gz] \
        [--cases case09,case02,case15|all] [--kinds clean,dropped,jitter,nan,dup,tip_offset,base_offset] \
        [--seed 7] [--keep DIR]

Each case of the independent set (rig.toml, sweep.csv and moves.csv to fit, validation.csv to
validate) is copied with one imperfection of what real loggers hand over, applied to all three
recordings alike, and diagnosed:
  clean        unchanged
  dropped      each row after the first two dropped with probability 1 % (dropped frames)
  jitter       time stamps off the grid by Gaussian sigma = 5 % of a step (values as recorded)
  nan          tip_pos_m blank in runs of 1-5 samples, a run starting with probability 0.3 %
  dup          a row written twice with probability 0.5 %
  tip_offset   tip_pos_m + 3 mm (a camera whose origin is not the beam's root)
  base_offset  base_pos_m + 0.2 mm (an encoder referenced to another home)
  force_offset force_n + 0.4 N
  reorder      the channel columns in reverse order
  t0           time_s + 1234.5 s
  tip_clip     tip_pos_m clipped at 80 % of its largest excursion either way (a camera's field of view)
  force_clip   force_n clipped likewise (a drive's current limit)
  glitch       tip_pos_m 5-50 mm off on ten runs of 1-3 samples per recording (a camera losing its marker)
  gaps         tip_pos_m and force_n each blank on three runs of 30-120 samples per recording, away from
               its first and last tenth (a marker lost for 0.3-1.2 s at 100 Hz; a force reading dropped)
  tip_flip     tip_pos_m negated (a camera whose axis points the other way)
  force_flip   force_n negated (a drive whose force sign is the opposite convention)
  base_flip    base_pos_m negated (an encoder counting down)
  slow_tip     tip_pos_m blank on every other row (a camera at half the rows' rate, logged beside the drive)
  units        time in ms, positions in mm (`time_ms`, `tip_pos_mm`, ...: a logger writing its own units)
  polled       rows taken at irregular times, 0.85-1.5 steps apart at random and stamped to 1 ms
               (a PC polling the drive), values interpolated (4-point cubic) from the recording
  combined     jitter (sigma 3 % of a step), then tip_offset, base_offset, nan, dropped, dup, all at once
Another rig's recordings rather than a logger's faults (the rig file follows where it must):
  half_rate    every other row (a camera at half the rate, no anti-alias filter; sample_rate_hz halved)
  noisy        tip_pos_m + Gaussian noise sigma 50 um, force_n + sigma 0.1 N, base_pos_m + sigma 2 um
  no_force     without force_n
  tip_only     without base_pos_m and force_n
  short        the first 60 % of each recording
  late_start   the first 15 % of each recording dropped (a logger started mid-motion)
One line per (case, kind): exit status, notes printed, named effects, unexplained channel,
validation NRMSE before/after on the best channel, run time, and whether the answer is right by
the scorer's rule (score_discrepancy.py: the named catalogue effects equal the key's; a named
`servo_lag` never counts against a case, every simulated rig having a position loop); then a
summary per kind.
"""
import argparse
import csv
import json
import os
import random
import subprocess
import sys
import tarfile
import tempfile
import time

FILES = ['sweep.csv', 'moves.csv', 'validation.csv']


def perturb(rows, kind, rng):
    head, data = rows[0], rows[1:]
    col = {h: i for i, h in enumerate(head)}

    def add(c, v):
        if c in col:
            for r in data:
                r[col[c]] = repr(float(r[col[c]]) + v)

    if kind == 'tip_offset':
        add('tip_pos_m', 0.003)
    elif kind == 'base_offset':
        add('base_pos_m', 2e-4)
    elif kind == 'force_offset':
        add('force_n', 0.4)
    elif kind == 't0':
        add('time_s', 1234.5)
    elif kind == 'dropped':
        data = [r for k, r in enumerate(data) if k < 2 or rng.random() > 0.01]
    elif kind == 'jitter':
        dt = float(data[1][0]) - float(data[0][0])
        for r in data:
            r[0] = repr(float(r[0]) + rng.gauss(0, 0.05 * dt))
    elif kind == 'nan':
        c, k = col['tip_pos_m'], 0
        while k < len(data):
            if rng.random() < 0.003:
                for j in range(k, min(k + rng.randint(1, 5), len(data))):
                    data[j][c] = ''
                k += 6
            else:
                k += 1
    elif kind == 'dup':
        out = []
        for r in data:
            out.append(r)
            if rng.random() < 0.005:
                out.append(list(r))
        data = out
    elif kind == 'reorder':
        perm = [0] + list(range(len(head) - 1, 0, -1))
        head = [head[i] for i in perm]
        data = [[r[i] for i in perm] for r in data]
    elif kind == 'half_rate':
        data = data[::2]
    elif kind == 'noisy':
        for c, sd in [('tip_pos_m', 5e-5), ('force_n', 0.1), ('base_pos_m', 2e-6)]:
            if c in col:
                for r in data:
                    r[col[c]] = repr(float(r[col[c]]) + rng.gauss(0, sd))
    elif kind in ('no_force', 'tip_only'):
        drop = {'force_n'} | ({'base_pos_m'} if kind == 'tip_only' else set())
        keep = [i for i, h in enumerate(head) if h not in drop]
        head = [head[i] for i in keep]
        data = [[r[i] for i in keep] for r in data]
    elif kind == 'short':
        data = data[:int(0.6 * len(data))]
    elif kind == 'late_start':
        data = data[int(0.15 * len(data)):]
    elif kind in ('tip_clip', 'force_clip'):
        # the sensor's range ends at 80 % of the largest excursion either way (a camera's field
        # of view, a drive's current limit): every sample beyond it reads the rail
        c = 'tip_pos_m' if kind == 'tip_clip' else 'force_n'
        if c in col:
            lim = 0.8 * max(abs(float(r[col[c]])) for r in data)
            for r in data:
                r[col[c]] = repr(max(-lim, min(lim, float(r[col[c]]))))
    elif kind == 'glitch':
        # a camera losing its marker: ten runs of 1-3 samples, 5-50 mm off, per recording
        if 'tip_pos_m' in col:
            c = col['tip_pos_m']
            for _ in range(10):
                k = rng.randrange(10, len(data) - 13)
                g = rng.choice([-1, 1]) * rng.uniform(0.005, 0.05)
                for j in range(rng.randint(1, 3)):
                    data[k + j][c] = repr(float(data[k + j][c]) + g * rng.uniform(0.8, 1.2))
    elif kind == 'gaps':
        # longer than any fill (recording::regular::MAX_FILL_RUN): left out of the comparison
        n = len(data)
        for c in ('tip_pos_m', 'force_n'):
            if c in col:
                for _ in range(3):
                    length = rng.randint(30, 120)
                    k = rng.randint(n // 10, n - n // 10 - length)
                    for r in data[k:k + length]:
                        r[col[c]] = ''
    elif kind in ('tip_flip', 'force_flip', 'base_flip'):
        c = {'tip_flip': 'tip_pos_m', 'force_flip': 'force_n', 'base_flip': 'base_pos_m'}[kind]
        if c in col:
            for r in data:
                r[col[c]] = repr(-float(r[col[c]]))
    elif kind == 'slow_tip':
        if 'tip_pos_m' in col:
            for k, r in enumerate(data):
                if k % 2:
                    r[col['tip_pos_m']] = ''
    elif kind == 'units':
        for i, h in enumerate(head):
            if h.endswith('_s') or h.endswith('_m'):
                head[i] = h[:-1] + 'ms' if h.endswith('_s') else h + 'm'
                for r in data:
                    r[i] = repr(1e3 * float(r[i])) if r[i] else r[i]
    elif kind == 'combined':
        dt = float(data[1][0]) - float(data[0][0])
        for r in data:
            r[0] = repr(float(r[0]) + rng.gauss(0, 0.03 * dt))
        rows = [head] + data
        for k in ['tip_offset', 'base_offset', 'nan', 'dropped', 'dup']:
            rows = perturb(rows, k, rng)
        head, data = rows[0], rows[1:]
    elif kind == 'polled':
        # a PC polling the drive: each row taken 0.85-1.5 recorded steps after the one before,
        # at random (85 % of steps short, 15 % long, stamped to 1 ms), values read off the
        # recording there by 4-point cubic (Catmull-Rom) interpolation
        dt = float(data[1][0]) - float(data[0][0])
        t_rec = [float(r[0]) for r in data]
        out, t = [], t_rec[1]
        while t <= t_rec[-3]:
            u = (t - t_rec[0]) / dt
            k = min(max(int(u), 1), len(data) - 3)
            f = u - k
            row = ['%.3f' % t]
            for c in range(1, len(head)):
                p0, p1, p2, p3 = (float(data[k + j][c]) if data[k + j][c] != '' else float('nan')
                                  for j in (-1, 0, 1, 2))
                v = p1 + 0.5 * f * (p2 - p0 + f * (2 * p0 - 5 * p1 + 4 * p2 - p3 + f * (3 * (p1 - p2) + p3 - p0)))
                row.append(repr(v))
            out.append(row)
            step = rng.uniform(1.2, 1.5) if rng.random() < 0.15 else rng.uniform(0.85, 1.05)
            t = round(t + step * dt, 3)
        data = out
    elif kind != 'clean':
        raise SystemExit('unknown kind ' + kind)
    return [head] + data


def rig_text(text, kind):
    """The rig file for `kind`: the sample rate halved for `half_rate`, else unchanged."""
    if kind != 'half_rate':
        return text
    out = []
    for line in text.splitlines(keepends=True):
        k, sep, v = line.partition('=')
        if sep and k.strip() == 'sample_rate_hz':
            line = '%s= %r\n' % (k, float(v) / 2)
        out.append(line)
    return ''.join(out)


def right(named, key_effect):
    """The scorer's rule: named catalogue effects equal the key's, `servo_lag` never against."""
    truth = set() if key_effect == 'none' else set(key_effect.split('+'))
    got = set(named) - {'none', 'unexplained', 'unknown', None}
    if 'servo_lag' not in truth:
        got.discard('servo_lag')
    return got == truth


def summary(out_json):
    d = json.load(open(out_json))
    named = [e['effect'] for e in d.get('effects', [])] or [d.get('effect')]
    unexpl = (d.get('unexplained') or {}).get('channel')
    v = d.get('validation') or {}
    nrmse = '%.4f -> %.4f' % (v.get('nrmse_before', float('nan')), v.get('nrmse_after', float('nan')))
    return named, '%s unexplained=%s nrmse %s' % ('+'.join(str(n) for n in named), unexpl, nrmse)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('tool')
    ap.add_argument('--set', default=os.path.join(os.path.dirname(__file__), '..', '..', 'shared', 'data',
                                                   'independent', 'discrepancy-v1.tar.gz'))
    ap.add_argument('--cases', default='case09,case02,case15')
    ap.add_argument('--kinds', default='clean,dropped,jitter,nan,dup,tip_offset,base_offset')
    ap.add_argument('--seed', type=int, default=7)
    ap.add_argument('--keep')
    a = ap.parse_args()
    tool = os.path.abspath(a.tool)
    work = a.keep or tempfile.mkdtemp(prefix='imperfect-')
    with tarfile.open(a.set) as t:
        t.extractall(work)
    src_root = os.path.join(work, 'hidden_gen')
    key = json.load(open(os.path.join(src_root, 'key.json')))
    cases = sorted(key) if a.cases == 'all' else a.cases.split(',')
    tally = {}
    for case in cases:
        for kind in a.kinds.split(','):
            rng = random.Random(a.seed)
            d = os.path.join(work, 'imperfect', case + '_' + kind)
            os.makedirs(d, exist_ok=True)
            with open(os.path.join(src_root, case, 'rig.toml')) as f, open(os.path.join(d, 'rig.toml'), 'w') as g:
                g.write(rig_text(f.read(), kind))
            for name in FILES:
                rows = list(csv.reader(open(os.path.join(src_root, case, name))))
                with open(os.path.join(d, name), 'w', newline='') as f:
                    csv.writer(f).writerows(perturb(rows, kind, rng))
            t0 = time.time()
            p = subprocess.run([tool, 'diagnose', '--rig', 'rig.toml', '--fit', 'sweep.csv', '--fit', 'moves.csv',
                                '--validate', 'validation.csv', '--json', 'out.json'],
                               cwd=d, capture_output=True, text=True)
            notes = sum(1 for line in p.stderr.splitlines() if line.startswith('note:'))
            if p.returncode == 0:
                named, res = summary(os.path.join(d, 'out.json'))
                ok = right(named, key[case]['effect'])
            else:
                ok, res = False, p.stderr.strip().splitlines()[-1]
            null = key[case]['effect'] == 'none'
            t = tally.setdefault(kind, [0, 0, 0, 0])
            t[0] += ok
            t[1] += 1
            t[2] += null and not ok
            t[3] += null
            print('%s %-12s rc=%d notes=%d %4.0fs %s %s' % (case, kind, p.returncode, notes, time.time() - t0, res,
                                                           'right' if ok else 'WRONG'), flush=True)
    for kind, (ok, n, fa, nulls) in tally.items():
        print('%-12s right %d/%d, false alarms %d/%d nulls' % (kind, ok, n, fa, nulls))


if __name__ == '__main__':
    sys.exit(main())
