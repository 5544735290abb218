//! The shaper's certificate (settings format version 3): `certify` records how `tune` checked
//! the installed shaper and the band it certified per mode slot; `status` and `config` show
//! it; a new shaper voids it; it persists in the record; a board of an earlier firmware reads
//! as "unknown". (The migration of a format-2 record is in `settings_codec.rs`.)

use beamshaper::config::{Certificate, Settings, Verified, SETTINGS_MAX_BYTES};
use beamshaper::protocol::{Command, ConfigReply, StatusReply};
use beamshaper_host_tests::Board;

fn last(out: &str) -> &str {
    out.lines().last().unwrap_or("")
}

#[test]
fn certify_shows_on_status_and_config_and_persists() {
    let mut b = Board::new();
    b.ok("mode 1 zv 1.1 0.0074");
    b.ok("mode 2 zv 6.9 0.0074");
    let st = StatusReply::parse(last(&b.ok("status"))).unwrap();
    assert_eq!(st.verified, Verified::Unknown);
    b.ok("certify predicted 1.078 1.122 6.76 7.04");
    let out = b.ok("status");
    assert!(last(&out).ends_with(" verified=predicted-only"), "{out}");
    assert_eq!(
        StatusReply::parse(last(&out)).unwrap().verified,
        Verified::PredictedOnly
    );
    let cfg = ConfigReply::parse(last(&b.ok("config"))).unwrap();
    assert_eq!(cfg.certificate.verified, Verified::PredictedOnly);
    assert_eq!(
        cfg.certificate.band_hz,
        [Some((1.078, 1.122)), Some((6.76, 7.04)), None, None]
    );
    // The record keeps it.
    let mut rec = [0u8; SETTINGS_MAX_BYTES];
    let n = b.console.settings().encode(&mut rec).unwrap();
    let back = Settings::decode(&rec[..n]).unwrap();
    assert_eq!(back.certificate, b.console.settings().certificate);
    // `measured` replaces it; the command line round-trips through the host's writer.
    let c = Command::parse("certify measured 1.078 1.122").unwrap();
    assert_eq!(c.to_string(), "certify measured 1.078 1.122");
    b.ok(&c.to_string());
    assert!(last(&b.ok("status")).ends_with(" verified=measured"));
}

#[test]
fn a_new_shaper_voids_the_certificate() {
    for change in [
        "mode 1 zvd 1.2 0.0074",
        "clear 2",
        "clear all",
        "custom 0.5@0 0.5@0.01",
    ] {
        let mut b = Board::new();
        b.ok("mode 1 zv 1.1 0.0074");
        b.ok("mode 2 zv 6.9 0.0074");
        b.ok("certify measured 1.07 1.13 6.7 7.1");
        b.ok(change);
        let st = StatusReply::parse(last(&b.ok("status"))).unwrap();
        assert_eq!(st.verified, Verified::Unknown, "after `{change}`");
        assert_eq!(b.console.settings().certificate, Certificate::NONE);
    }
    // Settings that do not change the shaper keep it.
    let mut b = Board::new();
    b.ok("mode 1 zv 1.1 0.0074");
    b.ok("certify measured 1.07 1.13");
    b.ok("speed 120");
    assert_eq!(
        b.console.settings().certificate.verified,
        Verified::Measured
    );
}

#[test]
fn bad_certificates_are_refused_and_change_nothing() {
    let mut b = Board::new();
    b.ok("mode 1 zv 1.1 0.0074");
    b.err("certify", "syntax");
    b.err("certify maybe", "syntax");
    b.err("certify measured 1.07", "syntax");
    b.err("certify measured 1.13 1.07", "range");
    b.err("certify measured -1 1.07", "range");
    b.err("certify measured 1.07 inf", "range");
    // A band for slot 2, which holds no mode.
    b.err("certify measured 1.07 1.13 6.7 7.1", "range");
    // `unknown` carries no band.
    b.err("certify unknown 1.07 1.13", "range");
    b.ok("certify unknown");
    assert_eq!(b.console.settings().certificate, Certificate::NONE);
}

#[test]
fn the_status_of_an_earlier_firmware_reads_as_unknown() {
    let mut b = Board::new();
    let line = last(&b.ok("status")).to_string();
    let old = line.replace(" verified=unknown", "");
    assert_ne!(old, line);
    assert_eq!(
        StatusReply::parse(&old).unwrap().verified,
        Verified::Unknown
    );
    let cfg = last(&b.ok("config")).to_string();
    let old = cfg[..cfg.find(" verified=").unwrap()].to_string();
    assert_eq!(
        ConfigReply::parse(&old).unwrap().certificate,
        Certificate::NONE
    );
}
