//! The ADXL357 driver (`beamshaper::sensor::adxl357`) on the host: the exact SPI traffic of
//! init (embedded-hal-mock), the 20-bit conversion, and a simulated chip (registers + a FIFO
//! of axis entries with x markers) for FIFO drains, overrun, lost alignment, wrong ids, bus
//! errors and stalls.

use beamshaper::sensor::adxl345::{Adxl345Error, Axis, G0_M_S2};
use beamshaper::sensor::adxl357::{
    convert_raw, raw20, reg, Adxl357, Adxl357Config, Range, DEVICE_ID,
};
use beamshaper::sensor::SensorEvent;
use embedded_hal::spi::{ErrorKind, ErrorType, Operation};
use embedded_hal_mock::eh1::spi::{Mock, Transaction as T};
use futures::executor::block_on;
use std::collections::VecDeque;

fn write(reg: u8, v: u8) -> Vec<T<u8>> {
    vec![
        T::transaction_start(),
        T::write_vec(vec![reg << 1, v]),
        T::transaction_end(),
    ]
}

fn read(reg: u8, v: Vec<u8>) -> Vec<T<u8>> {
    vec![
        T::transaction_start(),
        T::write_vec(vec![(reg << 1) | 1]),
        T::read_vec(v),
        T::transaction_end(),
    ]
}

#[test]
fn init_checks_the_ids_and_configures_range_and_rate() {
    let t = [
        read(reg::DEVID_AD, DEVICE_ID.to_vec()),
        write(reg::POWER_CTL, 0x01),
        write(reg::RANGE, 0x01),
        write(reg::FILTER, 0x00),
        read(reg::RANGE, vec![0x81]),
        read(reg::FILTER, vec![0x00]),
        write(reg::POWER_CTL, 0x02),
    ]
    .concat();
    let mut spi = Mock::new(&t);
    let cfg = block_on(Adxl357::new(spi.clone(), Adxl357Config::DEFAULT).init()).unwrap();
    assert_eq!(cfg.rate_hz, 4000.0);
    assert!((cfg.lsb_m_s2 - G0_M_S2 / 51_200.0).abs() < 1e-9);
    assert!((cfg.full_scale_m_s2 - 10.0 * G0_M_S2).abs() < 1e-3);
    spi.done();
}

#[test]
fn wrong_ids_are_refused() {
    for (id, bad) in [
        ([0xE5, 0x00, 0x00], 0xE5),
        ([0xAD, 0x1D, 0xEE], 0xEE),
        ([0xFF; 3], 0xFF),
    ] {
        let mut spi = Mock::new(&read(reg::DEVID_AD, id.to_vec()));
        let e = block_on(Adxl357::new(spi.clone(), Adxl357Config::DEFAULT).init()).unwrap_err();
        assert_eq!(e, Adxl345Error::WrongId(bad));
        spi.done();
    }
}

#[test]
fn twenty_bit_codes_and_ranges() {
    assert_eq!(raw20([0x00, 0x00, 0x10]), 1);
    assert_eq!(raw20([0x7F, 0xFF, 0xF0]), 524_287);
    assert_eq!(raw20([0x80, 0x00, 0x00]), -524_288);
    assert_eq!(raw20([0xFF, 0xFF, 0xF3]), -1); // marker bits ignored
    assert!((Range::G20.lsb_m_s2() - G0_M_S2 / 25_600.0).abs() < 1e-9);
    assert!((Range::G40.lsb_m_s2() - G0_M_S2 / 12_800.0).abs() < 1e-9);
    let c = Adxl357Config {
        axis: Axis::Z,
        ..Adxl357Config::DEFAULT
    };
    let s = convert_raw(&c, [0, 0, 51_200]);
    assert!((s.acc_m_s2 - G0_M_S2).abs() < 1e-4 && !s.saturated);
    assert!(convert_raw(&c, [0, 0, 512_000]).saturated);
    assert!(convert_raw(&c, [0, 0, -512_000]).saturated);
    assert!(!convert_raw(&c, [0, 0, 511_999]).saturated);
}

/// A simulated ADXL357: registers, a FIFO of 3-byte axis entries (x marked), STATUS.
struct FakeChip {
    regs: [u8; 64],
    fifo: VecDeque<[u8; 3]>,
    fail_at: Option<usize>,
    transactions: usize,
}

fn entry(v: i32, x: bool) -> [u8; 3] {
    let u = (v << 4) as u32;
    [(u >> 16) as u8, (u >> 8) as u8, (u as u8 & 0xF0) | x as u8]
}

impl FakeChip {
    fn new() -> Self {
        let mut regs = [0; 64];
        regs[..3].copy_from_slice(&DEVICE_ID);
        FakeChip {
            regs,
            fifo: VecDeque::new(),
            fail_at: None,
            transactions: 0,
        }
    }

    fn push_samples(&mut self, xs: impl IntoIterator<Item = i32>) {
        for x in xs {
            self.fifo
                .extend([entry(x, true), entry(-x, false), entry(7, false)]);
        }
    }

    fn read_into(&mut self, addr: usize, buf: &mut [u8]) {
        if addr == reg::FIFO_DATA as usize {
            for c in buf.chunks_mut(3) {
                let e = self.fifo.pop_front().unwrap_or([0, 0, 0x02]);
                c.copy_from_slice(&e[..c.len()]);
            }
            return;
        }
        self.regs[reg::FIFO_ENTRIES as usize] = self.fifo.len().min(96) as u8;
        for (i, b) in buf.iter_mut().enumerate() {
            *b = self.regs[addr + i];
        }
        if addr == reg::STATUS as usize {
            self.regs[reg::STATUS as usize] = 0; // cleared on read
        }
    }
}

impl ErrorType for FakeChip {
    type Error = ErrorKind;
}

impl embedded_hal_async::spi::SpiDevice for FakeChip {
    async fn transaction(&mut self, ops: &mut [Operation<'_, u8>]) -> Result<(), ErrorKind> {
        self.transactions += 1;
        if self.fail_at == Some(self.transactions) {
            return Err(ErrorKind::Other);
        }
        let mut addr = None;
        for op in ops {
            match op {
                Operation::Write(w) if w[0] & 1 == 1 => addr = Some((w[0] >> 1) as usize),
                Operation::Write(w) => {
                    let a = (w[0] >> 1) as usize;
                    self.regs[a..a + w.len() - 1].copy_from_slice(&w[1..]);
                }
                Operation::Read(buf) => self.read_into(addr.ok_or(ErrorKind::Other)?, buf),
                _ => return Err(ErrorKind::Other),
            }
        }
        Ok(())
    }
}

fn drain(chip: &mut Adxl357<FakeChip>) -> (Result<u8, Adxl345Error<ErrorKind>>, Vec<SensorEvent>) {
    let mut events = Vec::new();
    let r = block_on(chip.read_fifo(&mut |e| events.push(e))).map(|r| r.samples);
    (r, events)
}

fn values(events: &[SensorEvent]) -> Vec<Option<i32>> {
    let lsb = Range::G10.lsb_m_s2();
    events
        .iter()
        .map(|e| match e {
            SensorEvent::Sample(s) => Some((s.acc_m_s2 / lsb).round() as i32),
            SensorEvent::Lost => None,
        })
        .collect()
}

#[test]
fn simulated_chip_streams_samples_in_order() {
    let mut chip = Adxl357::new(FakeChip::new(), Adxl357Config::DEFAULT);
    block_on(chip.init()).unwrap();
    let mut fake = chip.release();
    assert_eq!(fake.regs[reg::POWER_CTL as usize], 0x02);
    fake.push_samples([10, -20, 30_000, -400_000]);
    let mut chip = Adxl357::new(fake, Adxl357Config::DEFAULT);
    let (r, events) = drain(&mut chip);
    assert_eq!(r, Ok(4));
    assert_eq!(
        values(&events),
        vec![Some(10), Some(-20), Some(30_000), Some(-400_000)]
    );
}

#[test]
fn overrun_and_lost_alignment_are_lost_then_resynchronised() {
    let mut fake = FakeChip::new();
    fake.regs[reg::STATUS as usize] = 0x04;
    fake.push_samples([1, 2]);
    let mut chip = Adxl357::new(fake, Adxl357Config::DEFAULT);
    let (r, events) = drain(&mut chip);
    assert_eq!(r, Ok(2));
    assert_eq!(values(&events), vec![None, Some(1), Some(2)]);
    // A stream that starts mid-sample (y, z of a lost sample) re-aligns on the next x.
    let mut fake = chip.release();
    fake.fifo.extend([entry(5, false), entry(6, false)]);
    fake.push_samples([3, 4]);
    let mut chip = Adxl357::new(fake, Adxl357Config::DEFAULT);
    let (r, events) = drain(&mut chip);
    assert_eq!(r, Ok(2));
    assert_eq!(values(&events), vec![None, Some(3), Some(4)]);
}

#[test]
fn bus_errors_stalls_and_a_stuck_bus_are_errors() {
    let mut fake = FakeChip::new();
    fake.push_samples([1, 2, 3]);
    fake.fail_at = Some(3); // status, sample 1, then the failure
    let mut chip = Adxl357::new(fake, Adxl357Config::DEFAULT);
    let (r, events) = drain(&mut chip);
    assert_eq!(r, Err(Adxl345Error::Bus(ErrorKind::Other)));
    assert_eq!(values(&events), vec![Some(1)]);
    let mut chip = Adxl357::new(FakeChip::new(), Adxl357Config::DEFAULT);
    assert_eq!(drain(&mut chip).0, Ok(0));
    assert_eq!(drain(&mut chip).0, Ok(0));
    assert_eq!(drain(&mut chip).0, Err(Adxl345Error::Stalled));
    let mut fake = FakeChip::new();
    fake.regs = [0xFF; 64];
    let mut chip = Adxl357::new(fake, Adxl357Config::DEFAULT);
    assert_eq!(block_on(chip.init()), Err(Adxl345Error::WrongId(0xFF)));
}
