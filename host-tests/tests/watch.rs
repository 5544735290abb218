//! The drift watch through the console (`watch …`, `payload …`), on a simulated two-mode beam
//! (1.1 Hz and 6.9 Hz, ζ = 0.0074) with an ADXL345-like sensor: a healthy sensor gives the
//! beam's f1; a sensor that stops answering, loses samples, saturates or reads a constant
//! gives `state=no_sensor` or `saturated`, no frequency and no retune.

use beamshaper::protocol::WatchReply;
use beamshaper::sensor::{AccelConfig, AccelSample, SensorEvent};
use beamshaper::watch::WatchState;
use beamshaper_host_tests::Board;

const LSB: f32 = 0.0383;

/// How the simulated sensor misbehaves.
#[derive(Clone, Copy, PartialEq)]
enum Fault {
    None,
    Silent,
    Lost,
    Saturates,
    Constant,
}

/// A two-mode beam on the carriage, stepped with the board's shaped setpoint each tick.
struct Beam {
    eta: [(f64, f64); 2],
    sp: [f64; 2],
    noise: u64,
}

impl Beam {
    fn tick(&mut self, sp_nm: i32) -> f64 {
        let sp = sp_nm as f64 * 1e-9;
        let a = (sp - 2.0 * self.sp[0] + self.sp[1]) * 1e6;
        self.sp = [sp, self.sp[0]];
        let mut acc = a;
        for (e, (f, g)) in self.eta.iter_mut().zip([(1.1, 1.57), (6.9, 0.87)]) {
            let w = 2.0 * std::f64::consts::PI * f;
            let dd = -g * a - 2.0 * 0.0074 * w * e.1 - w * w * e.0;
            e.1 += dd * 1e-3;
            e.0 += e.1 * 1e-3;
            acc += dd;
        }
        acc
    }

    fn noise(&mut self) -> f64 {
        self.noise = self.noise.wrapping_mul(6364136223846793005).wrapping_add(1);
        ((self.noise >> 40) as f64 / (1u64 << 24) as f64 - 0.5) * 0.2
    }
}

/// Boots a board with a ZV*ZV shaper at 1.1 / 6.9 Hz, the watch on (auto on, limits 0.5–10 Hz),
/// then runs `moves` moves with the sensor misbehaving as `fault` from the second move on.
fn run(fault: Fault, moves: usize) -> (Board, WatchReply) {
    let mut b = Board::new();
    b.ok("mode 1 zv 1.1 0.0074");
    b.ok("mode 2 zv 6.9 0.0074");
    let full_scale = if fault == Fault::Saturates {
        0.5
    } else {
        156.9
    };
    b.console.set_accel(
        Some(AccelConfig {
            rate_hz: 3200.0,
            full_scale_m_s2: full_scale,
            lsb_m_s2: LSB,
        }),
        &mut *b.rt,
    );
    b.ok("watch limits 0.5 10");
    b.ok("watch on");
    b.ok("watch auto on");
    let mut beam = Beam {
        eta: [(0.0, 0.0); 2],
        sp: [0.0; 2],
        noise: 3,
    };
    let mut target = 100.0;
    for n in 0..moves {
        b.ok(&format!("move {target} 150 2000"));
        target = 100.0 - target;
        let faulty = n >= 1 && fault != Fault::None;
        for k in 0..4500u32 {
            let out = b.rt.tick(&Default::default());
            let acc = beam.tick(out.setpoint_counts);
            let count = 3 + u32::from(k % 5 == 4);
            for _ in 0..count {
                let v = acc + beam.noise();
                let q = ((v / LSB as f64).round() * LSB as f64) as f32;
                let ev = match fault {
                    _ if !faulty => SensorEvent::Sample(AccelSample {
                        acc_m_s2: q,
                        saturated: false,
                    }),
                    Fault::Silent => continue,
                    Fault::Lost if k == 300 => SensorEvent::Lost,
                    Fault::Saturates => SensorEvent::Sample(AccelSample {
                        acc_m_s2: q.clamp(-full_scale, full_scale),
                        saturated: q.abs() >= full_scale,
                    }),
                    Fault::Constant => SensorEvent::Sample(AccelSample {
                        acc_m_s2: 0.3,
                        saturated: false,
                    }),
                    _ => SensorEvent::Sample(AccelSample {
                        acc_m_s2: q,
                        saturated: false,
                    }),
                };
                b.console.watch_event(ev);
            }
            if k % 10 == 9 {
                b.console.watch_poll(&mut *b.rt);
            }
        }
    }
    let r = b.ok("watch");
    let w = WatchReply::parse(r.lines().last().unwrap()).unwrap();
    (b, w)
}

#[test]
fn a_healthy_sensor_measures_the_beam() {
    let (_, w) = run(Fault::None, 3);
    assert_eq!(w.state, WatchState::Ok, "{w:?}");
    assert_eq!(w.moves, 3);
    let f1 = w.f1_hz.unwrap();
    assert!((f1 / 1.1 - 1.0).abs() < 0.01, "{f1}");
    assert!((w.f2_hz.unwrap() / 6.9 - 1.0).abs() < 0.02, "{w:?}");
    assert_eq!(w.retunes, 0);
}

#[test]
fn bad_sensors_give_no_frequency_and_no_retune() {
    for (fault, want) in [
        (Fault::Silent, WatchState::NoSensor),
        (Fault::Lost, WatchState::NoSensor),
        (Fault::Saturates, WatchState::Saturated),
        (Fault::Constant, WatchState::NoSensor),
    ] {
        let (b, w) = run(fault, 3);
        assert_eq!(w.state, want, "{w:?}");
        assert_eq!(w.f1_hz, None, "{w:?}");
        assert_eq!(w.retunes, 0);
        assert_eq!(b.console.settings().modes[0].unwrap().freq_hz, 1.1);
    }
}

#[test]
fn no_sensor_at_all_says_no_sensor() {
    let mut b = Board::new();
    b.ok("mode 1 zv 1.1 0.0074");
    b.ok("watch on");
    let r = b.ok("watch");
    assert!(r.contains("state=no_sensor"), "{r}");
}

#[test]
fn watch_and_payload_commands_validate_and_persist() {
    let mut b = Board::new();
    b.err("watch limits 3 1", "range");
    b.err("watch auto on", "range");
    b.err("watch sideways", "syntax");
    b.ok("watch limits 0.5 3");
    assert!(b.ok("watch auto on").contains("no setpoint jump"));
    b.err("payload 2", "range");
    b.err("payload 8", "range");
    b.ok("mode 1 zv 1.1 0.0074");
    b.ok("payload 2 store");
    b.ok("mode 1 zv 1.3 0.0074");
    b.ok("payload 3 store");
    b.ok("payload 2");
    assert_eq!(
        b.console.settings().modes[0].unwrap().freq_hz,
        1.1f32 as f64
    );
    let r = b.ok("payload");
    assert!(r.contains("# payload 3 f_hz=1.3,-,-,-"), "{r}");
    assert!(r.contains("ok payload selected=2 entries=2"), "{r}");
    let mut buf = [0u8; beamshaper::config::SETTINGS_MAX_BYTES];
    let n = b.console.settings().encode(&mut buf).unwrap();
    let back = beamshaper::config::Settings::decode(&buf[..n]).unwrap();
    assert_eq!(&back, b.console.settings());
    assert!(back.watch.auto && back.watch.limits_hz == (0.5, 3.0));
}

/// The search grids' constant ratios are what their documentation says.
#[test]
fn grid_ratios_match_their_definitions() {
    use beamshaper::watch::modal::{FREQ_GRID, FREQ_RATIOS, ZETA_GRID, ZETA_RANGE, ZETA_RATIOS};
    use beamshaper::watch::MATCH_RANGE;
    let r = MATCH_RANGE;
    let q = ((1.0 + r) / (1.0 - r)).powf(1.0 / (FREQ_GRID - 1) as f64);
    let z = (ZETA_RANGE.1 as f64 / ZETA_RANGE.0 as f64).powf(1.0 / (ZETA_GRID - 1) as f64);
    for (got, want) in [
        (FREQ_RATIOS.0, q),
        (FREQ_RATIOS.1[0], q.sqrt()),
        (FREQ_RATIOS.1[1], q.powf(0.25)),
        (FREQ_RATIOS.2, 0.25 * q.ln()),
        (ZETA_RATIOS.0, z),
        (ZETA_RATIOS.1[0], z.sqrt()),
        (ZETA_RATIOS.1[1], z.powf(0.25)),
        (ZETA_RATIOS.2, 0.25 * z.ln()),
    ] {
        assert!((got as f64 / want - 1.0).abs() < 1e-4, "{got} vs {want}");
    }
}
