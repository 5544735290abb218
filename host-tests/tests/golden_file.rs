//! The on-target test suite (`tests/on_target.rs`, NUCLEO-G474RE) compares the board's
//! golden vectors with `tests/golden-host.txt`: that file must be exactly what the host
//! computes now (regenerate it with `cd host-tests && cargo run --release --bin golden >
//! ../tests/golden-host.txt` after a deliberate change of the vectors).

#[test]
fn committed_golden_file_is_the_hosts_output() {
    let mut now = String::new();
    beamshaper::golden::write_golden(&mut now).unwrap();
    let committed = include_str!("../../tests/golden-host.txt");
    assert!(
        now == committed,
        "tests/golden-host.txt is stale: regenerate it (see this file's header)"
    );
}

#[test]
fn golden_in_a_static_slot_is_the_same_text() {
    let mut slot = Box::new(core::mem::MaybeUninit::uninit());
    let (mut a, mut b) = (String::new(), String::new());
    beamshaper::golden::write_golden(&mut a).unwrap();
    beamshaper::golden::write_golden_in(&mut b, &mut slot).unwrap();
    assert_eq!(a, b);
}
