//! The ADXL345 driver (`beamshaper::sensor::adxl345`) on the host: the exact SPI traffic of
//! the init sequence and of a FIFO drain (embedded-hal-mock), and a simulated chip (register
//! file + 32-entry FIFO) for the failures: wrong device id, bus errors, FIFO overrun, stall,
//! saturation. Plus the queue gate and the health counters of `beamshaper::sensor`.

use beamshaper::sensor::adxl345::{
    convert_raw, reg, Adxl345, Adxl345Config, Adxl345Error, Axis, Rate, DEVICE_ID, FIFO_POP_GAP_NS,
    FORMAT_FULL_RES_16G, G0_M_S2,
};
use beamshaper::sensor::{AccelSample, EventGate, SensorEvent, SensorHealth};
use embedded_hal::spi::{ErrorKind, ErrorType, Operation};
use embedded_hal_mock::eh1::spi::{Mock, Transaction as T};
use futures::executor::block_on;
use std::collections::VecDeque;

const LSB: f32 = 0.0039 * G0_M_S2;

fn write(reg: u8, v: u8) -> Vec<T<u8>> {
    vec![
        T::transaction_start(),
        T::write_vec(vec![reg, v]),
        T::transaction_end(),
    ]
}

fn read(reg: u8, v: u8) -> Vec<T<u8>> {
    vec![
        T::transaction_start(),
        T::transfer_in_place(vec![0x80 | reg, 0], vec![0x80 | reg, v]),
        T::transaction_end(),
    ]
}

fn entry(x: i16, y: i16, z: i16) -> Vec<T<u8>> {
    let mut resp = vec![0xF2];
    for v in [x, y, z] {
        resp.extend_from_slice(&v.to_le_bytes());
    }
    vec![
        T::transaction_start(),
        T::transfer_in_place(vec![0xF2, 0, 0, 0, 0, 0, 0], resp),
        T::delay(FIFO_POP_GAP_NS),
        T::transaction_end(),
    ]
}

fn init_traffic(rate_code: u8) -> Vec<T<u8>> {
    [
        read(reg::DEVID, DEVICE_ID),
        write(reg::POWER_CTL, 0),
        write(reg::DATA_FORMAT, 0x0B),
        write(reg::BW_RATE, rate_code),
        write(reg::INT_ENABLE, 0),
        write(reg::FIFO_CTL, 0),
        write(reg::FIFO_CTL, 0x80),
        read(reg::DATA_FORMAT, 0x0B),
        read(reg::BW_RATE, rate_code),
        write(reg::POWER_CTL, 0x08),
    ]
    .concat()
}

#[test]
fn init_sends_the_datasheet_sequence_and_reports_the_stream() {
    let mut spi = Mock::new(&init_traffic(0x0F));
    let mut chip = Adxl345::new(spi.clone(), Adxl345Config::DEFAULT);
    let cfg = block_on(chip.init()).unwrap();
    assert_eq!(cfg.rate_hz, 3200.0);
    assert!((cfg.lsb_m_s2 - 0.038_246).abs() < 1e-5);
    assert!((cfg.full_scale_m_s2 - 4096.0 * 0.038_246).abs() < 0.05);
    spi.done();
}

#[test]
fn init_at_800_hz_writes_its_rate_code() {
    let mut spi = Mock::new(&init_traffic(0x0D));
    let config = Adxl345Config {
        rate: Rate::Hz800,
        ..Adxl345Config::DEFAULT
    };
    let cfg = block_on(Adxl345::new(spi.clone(), config).init()).unwrap();
    assert_eq!(cfg.rate_hz, 800.0);
    spi.done();
}

#[test]
fn wrong_device_id_is_refused_before_any_write() {
    for id in [0x00, 0xFF, 0xE6, 0xAD] {
        let mut spi = Mock::new(&read(reg::DEVID, id));
        let mut chip = Adxl345::new(spi.clone(), Adxl345Config::DEFAULT);
        let e = block_on(chip.init()).unwrap_err();
        assert_eq!(e, Adxl345Error::WrongId(id));
        assert_eq!(e.event(), SensorEvent::Lost);
        spi.done();
    }
}

#[test]
fn a_format_that_does_not_read_back_is_refused() {
    let mut t = init_traffic(0x0F);
    // Replace the DATA_FORMAT read-back (after the 7 writes and the id read) by 0x00.
    let at = t.len() - 3 - 3 * 2;
    t.splice(at..at + 3, read(reg::DATA_FORMAT, 0x00));
    t.truncate(t.len() - 3 * 2);
    let mut spi = Mock::new(&t);
    let e = block_on(Adxl345::new(spi.clone(), Adxl345Config::DEFAULT).init()).unwrap_err();
    assert_eq!(
        e,
        Adxl345Error::Readback {
            reg: reg::DATA_FORMAT,
            wrote: FORMAT_FULL_RES_16G,
            read: 0
        }
    );
    spi.done();
}

#[test]
fn fifo_drain_reads_status_then_each_entry_with_the_gap() {
    let t = [
        read(reg::FIFO_STATUS, 3),
        entry(100, -5, 256),
        entry(-100, 7, 255),
        entry(0, 0, 0),
    ]
    .concat();
    let mut spi = Mock::new(&t);
    let mut chip = Adxl345::new(spi.clone(), Adxl345Config::DEFAULT);
    let mut events = Vec::new();
    let r = block_on(chip.read_fifo(&mut |e| events.push(e))).unwrap();
    assert_eq!((r.samples, r.overrun, r.saturated), (3, false, 0));
    let acc: Vec<f32> = events
        .iter()
        .map(|e| match e {
            SensorEvent::Sample(s) => s.acc_m_s2,
            SensorEvent::Lost => f32::NAN,
        })
        .collect();
    assert_eq!(acc, vec![100.0 * LSB, -100.0 * LSB, 0.0]);
    spi.done();
}

#[test]
fn conversion_picks_the_axis_inverts_and_flags_full_scale() {
    let c = |axis, invert| Adxl345Config {
        axis,
        invert,
        ..Adxl345Config::DEFAULT
    };
    let raw = [1, -2, 256];
    assert_eq!(convert_raw(&c(Axis::Y, false), raw).acc_m_s2, -2.0 * LSB);
    // 256 LSB ≈ 1 g on Z (the typical full-resolution scale).
    let z = convert_raw(&c(Axis::Z, true), raw);
    assert!((z.acc_m_s2 + 256.0 * LSB).abs() < 1e-6);
    assert!((z.acc_m_s2 + 9.79).abs() < 0.03);
    for (v, sat) in [
        (4094, false),
        (4095, true),
        (-4095, false),
        (-4096, true),
        (i16::MIN, true),
    ] {
        let s = convert_raw(&c(Axis::X, false), [v, 0, 0]);
        assert_eq!(s.saturated, sat, "raw {v}");
        assert_eq!(s.acc_m_s2, v as f32 * LSB);
    }
}

/// A simulated ADXL345 behind an async `SpiDevice`: 64 registers, a FIFO of raw entries,
/// optional bus failure on the n-th transaction.
struct FakeChip {
    regs: [u8; 64],
    fifo: VecDeque<[i16; 3]>,
    fail_at: Option<usize>,
    transactions: usize,
}

impl FakeChip {
    fn new(id: u8) -> Self {
        let mut regs = [0; 64];
        regs[0] = id;
        FakeChip {
            regs,
            fifo: VecDeque::new(),
            fail_at: None,
            transactions: 0,
        }
    }

    /// Handles one address byte + data; FIFO pops on a multi-byte read of DATAX0.
    fn exchange(&mut self, buf: &mut [u8]) {
        let (cmd, data) = buf.split_first_mut().unwrap();
        let addr = (*cmd & 0x3F) as usize;
        if *cmd & 0x80 == 0 {
            for (i, b) in data.iter().enumerate() {
                self.regs[addr + i] = *b;
            }
            return;
        }
        if addr == reg::DATAX0 as usize && data.len() == 6 {
            let e = self.fifo.pop_front().unwrap_or([0; 3]);
            for (i, v) in e.iter().enumerate() {
                data[2 * i..2 * i + 2].copy_from_slice(&v.to_le_bytes());
            }
            return;
        }
        if addr == reg::FIFO_STATUS as usize {
            data[0] = self.fifo.len().min(32) as u8;
            return;
        }
        for (i, b) in data.iter_mut().enumerate() {
            *b = self.regs[addr + i];
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
        for op in ops {
            match op {
                Operation::TransferInPlace(buf) => self.exchange(buf),
                Operation::Write(buf) => self.exchange(&mut buf.to_vec()),
                Operation::DelayNs(_) => {}
                _ => return Err(ErrorKind::Other),
            }
        }
        Ok(())
    }
}

fn drain(chip: &mut Adxl345<FakeChip>) -> (Result<u8, Adxl345Error<ErrorKind>>, Vec<SensorEvent>) {
    let mut events = Vec::new();
    let r = block_on(chip.read_fifo(&mut |e| events.push(e))).map(|r| r.samples);
    (r, events)
}

#[test]
fn simulated_chip_streams_samples_in_order() {
    let mut chip = Adxl345::new(FakeChip::new(DEVICE_ID), Adxl345Config::DEFAULT);
    block_on(chip.init()).unwrap();
    let fake = chip.release();
    assert_eq!(fake.regs[reg::POWER_CTL as usize], 0x08);
    assert_eq!(fake.regs[reg::FIFO_CTL as usize], 0x80);
    let mut fake = fake;
    fake.fifo.extend((0..20).map(|k| [k, 0, 0]));
    let mut chip = Adxl345::new(fake, Adxl345Config::DEFAULT);
    let (r, events) = drain(&mut chip);
    assert_eq!(r, Ok(20));
    for (k, e) in events.iter().enumerate() {
        assert_eq!(
            *e,
            SensorEvent::Sample(AccelSample {
                acc_m_s2: k as f32 * LSB,
                saturated: false
            })
        );
    }
}

#[test]
fn full_fifo_is_an_overrun_lost_before_the_samples() {
    let mut fake = FakeChip::new(DEVICE_ID);
    fake.fifo.extend((0..40).map(|k| [k, 0, 0]));
    let mut chip = Adxl345::new(fake, Adxl345Config::DEFAULT);
    let mut events = Vec::new();
    let r = block_on(chip.read_fifo(&mut |e| events.push(e))).unwrap();
    assert!(r.overrun);
    assert_eq!(r.samples, 32);
    assert_eq!(events[0], SensorEvent::Lost);
    assert_eq!(events.len(), 33);
}

#[test]
fn status_33_is_a_full_fifo_read_whole_and_34_is_refused() {
    let mut t = read(reg::FIFO_STATUS, 33);
    for k in 0..33 {
        t.extend(entry(k, 0, 0));
    }
    let mut spi = Mock::new(&t);
    let mut chip = Adxl345::new(spi.clone(), Adxl345Config::DEFAULT);
    let mut events = Vec::new();
    let r = block_on(chip.read_fifo(&mut |e| events.push(e))).unwrap();
    assert_eq!((r.samples, r.overrun), (33, true));
    assert_eq!(events[0], SensorEvent::Lost);
    assert_eq!(events.len(), 34);
    spi.done();
    let mut spi = Mock::new(&read(reg::FIFO_STATUS, 34));
    let mut chip = Adxl345::new(spi.clone(), Adxl345Config::DEFAULT);
    let r = block_on(chip.read_fifo(&mut |_| {}));
    assert_eq!(r, Err(Adxl345Error::Status(34)));
    spi.done();
}

#[test]
fn bus_error_mid_burst_keeps_the_samples_before_it() {
    let mut fake = FakeChip::new(DEVICE_ID);
    fake.fifo.extend((0..5).map(|k| [k, 0, 0]));
    fake.fail_at = Some(4); // status, entry 0, entry 1, then the failure
    let mut chip = Adxl345::new(fake, Adxl345Config::DEFAULT);
    let (r, events) = drain(&mut chip);
    assert_eq!(r, Err(Adxl345Error::Bus(ErrorKind::Other)));
    assert_eq!(events.len(), 2);
    // On init: the id read fails.
    let mut fake = FakeChip::new(DEVICE_ID);
    fake.fail_at = Some(1);
    let e = block_on(Adxl345::new(fake, Adxl345Config::DEFAULT).init()).unwrap_err();
    assert_eq!(e, Adxl345Error::Bus(ErrorKind::Other));
    assert_eq!(e.event(), SensorEvent::Lost);
}

#[test]
fn a_bus_stuck_high_or_low_is_reported_not_read_as_data() {
    // Stuck high: every byte 0xFF, so the id is wrong and FIFO_STATUS claims 63 entries.
    let mut fake = FakeChip::new(0xFF);
    fake.regs = [0xFF; 64];
    let mut chip = Adxl345::new(fake, Adxl345Config::DEFAULT);
    assert_eq!(block_on(chip.init()), Err(Adxl345Error::WrongId(0xFF)));
    let mut spi = Mock::new(&read(reg::FIFO_STATUS, 0xFF));
    let mut chip = Adxl345::new(spi.clone(), Adxl345Config::DEFAULT);
    let r = block_on(chip.read_fifo(&mut |_| panic!("no event expected")));
    assert_eq!(r, Err(Adxl345Error::Status(0xFF)));
    spi.done();
    // Stuck low (or a chip that reset into standby): empty FIFO, stalled after 3 reads.
    let mut chip = Adxl345::new(FakeChip::new(0), Adxl345Config::DEFAULT);
    assert_eq!(drain(&mut chip).0, Ok(0));
    assert_eq!(drain(&mut chip).0, Ok(0));
    assert_eq!(drain(&mut chip).0, Err(Adxl345Error::Stalled));
    // After reporting the stall the count starts again.
    assert_eq!(drain(&mut chip).0, Ok(0));
}

#[test]
fn saturated_samples_are_counted_and_flagged() {
    let mut fake = FakeChip::new(DEVICE_ID);
    fake.fifo.extend([[4095, 0, 0], [100, 0, 0], [-4096, 0, 0]]);
    let mut chip = Adxl345::new(fake, Adxl345Config::DEFAULT);
    let mut events = Vec::new();
    let r = block_on(chip.read_fifo(&mut |e| events.push(e))).unwrap();
    assert_eq!(r.saturated, 2);
    let flags: Vec<bool> = events
        .iter()
        .map(|e| matches!(e, SensorEvent::Sample(s) if s.saturated))
        .collect();
    assert_eq!(flags, vec![true, false, true]);
}

#[test]
fn gate_marks_a_full_queue_with_one_lost() {
    let mut gate = EventGate::new();
    let mut queue: Vec<SensorEvent> = Vec::new();
    let s = |v: f32| {
        SensorEvent::Sample(AccelSample {
            acc_m_s2: v,
            saturated: false,
        })
    };
    let cap = 3;
    let send = |q: &mut Vec<SensorEvent>, e| {
        if q.len() < cap {
            q.push(e);
            true
        } else {
            false
        }
    };
    for k in 0..5 {
        gate.push(s(k as f32), |e| send(&mut queue, e));
    }
    assert_eq!(gate.dropped, 2);
    queue.clear();
    assert!(gate.push(s(9.0), |e| send(&mut queue, e)));
    assert_eq!(queue, vec![SensorEvent::Lost, s(9.0)]);
    // A Lost owed and a Lost pushed are one Lost.
    let mut gate = EventGate::new();
    let mut q2 = Vec::new();
    gate.push(s(1.0), |_| false);
    assert!(gate.push(SensorEvent::Lost, |e| send(&mut q2, e)));
    assert_eq!(q2, vec![SensorEvent::Lost]);
}

#[test]
fn health_counts_samples_losses_and_saturation() {
    let mut h = SensorHealth::new();
    let sat = SensorEvent::Sample(AccelSample {
        acc_m_s2: 160.0,
        saturated: true,
    });
    let ok = SensorEvent::Sample(AccelSample {
        acc_m_s2: 1.5,
        saturated: false,
    });
    for e in [ok, sat, SensorEvent::Lost, ok] {
        h.record(&e);
    }
    assert_eq!((h.samples, h.lost, h.saturated, h.run), (3, 1, 1, 1));
    assert_eq!(h.last_m_s2, 1.5);
}
