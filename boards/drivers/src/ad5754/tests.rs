use super::*;
use embedded_hal::spi::{ErrorKind as SpiKind, ErrorType, Operation};
use embedded_hal_mock::eh1::delay::NoopDelay;
use embedded_hal_mock::eh1::digital::{Mock as Pin, State, Transaction as PinT};
use embedded_hal_mock::eh1::spi::{Mock as Spi, Transaction as SpiT};
use embedded_hal_mock::eh1::MockError;
use rths_core::hal::{Error as _, ErrorKind};

fn write(bytes: [u8; 3]) -> Vec<SpiT<u8>> {
    vec![
        SpiT::transaction_start(),
        SpiT::write_vec(bytes.to_vec()),
        SpiT::transaction_end(),
    ]
}

fn ldac_pulse() -> Vec<PinT> {
    vec![PinT::set(State::Low), PinT::set(State::High)]
}

/// The exact power-up sequence, with `readback` as the range register's content.
fn init_spi(channel: u8, readback: u16) -> Vec<SpiT<u8>> {
    let mut t = Vec::new();
    t.extend(write([0x04, 0x00, 0x00])); // DAC register, all channels, 0 V
    t.extend(write([0x0C, 0x00, 0x04])); // range register, all channels, ±10 V
    t.extend(write([0x88 | channel, 0x00, 0x00])); // read the range of our channel
    let [hi, lo] = readback.to_be_bytes();
    t.push(SpiT::transaction_start());
    t.push(SpiT::transfer(
        vec![0x18, 0x00, 0x00],
        vec![0x08 | channel, hi, lo],
    ));
    t.push(SpiT::transaction_end());
    t
}

#[test]
fn frames_follow_the_data_sheet_layout() {
    assert_eq!(frame(false, REG_DAC, 0, 0x1234), [0x00, 0x12, 0x34]);
    assert_eq!(frame(false, REG_DAC, 3, 0xFFFF), [0x03, 0xFF, 0xFF]);
    assert_eq!(
        frame(false, REG_RANGE, ADDR_ALL, RANGE_PM10V),
        [0x0C, 0x00, 0x04]
    );
    assert_eq!(frame(false, REG_POWER, 0, POWER_ALL_UP), [0x10, 0x00, 0x2F]);
    assert_eq!(frame(true, REG_RANGE, 1, 0), [0x89, 0x00, 0x00]);
    assert_eq!(NOP, [0x18, 0x00, 0x00]);
}

#[test]
fn volts_to_code_rounds_and_clips() {
    assert_eq!(volts_to_code(0.0), (0, false));
    assert_eq!(volts_to_code(5.0), (16384, false));
    assert_eq!(volts_to_code(-5.0), (-16384, false));
    assert_eq!(volts_to_code(-10.0), (i16::MIN, false));
    // +10 V is one LSB beyond the top code (+10 V − 1 LSB): clipped, and said so.
    assert_eq!(volts_to_code(10.0), (i16::MAX, true));
    assert_eq!(volts_to_code(10.0 - DAC_VOLTS_PER_CODE), (i16::MAX, false));
    assert_eq!(volts_to_code(10.01), (i16::MAX, true));
    assert_eq!(volts_to_code(-10.01), (i16::MIN, true));
    assert_eq!(volts_to_code(f64::NAN), (0, true));
    assert_eq!(volts_to_code(f64::INFINITY), (i16::MAX, true));
    // Rounding to nearest: 0.6 LSB → 1, 0.4 LSB → 0, −0.6 LSB → −1.
    assert_eq!(volts_to_code(0.6 * DAC_VOLTS_PER_CODE).0, 1);
    assert_eq!(volts_to_code(0.4 * DAC_VOLTS_PER_CODE).0, 0);
    assert_eq!(volts_to_code(-0.6 * DAC_VOLTS_PER_CODE).0, -1);
}

#[test]
fn code_volts_round_trip_within_half_an_lsb() {
    for i in -1000..=1000 {
        let v = i as f64 * 0.00999;
        let (c, clip) = volts_to_code(v);
        assert!(!clip);
        assert!(
            (code_to_volts(c) - v).abs() <= 0.5 * DAC_VOLTS_PER_CODE + 1e-12,
            "{v}"
        );
    }
}

#[test]
fn init_sets_the_range_checks_it_powers_up_and_latches_zero() {
    let mut spi_t = init_spi(0, RANGE_PM10V);
    spi_t.extend(write([0x10, 0x00, 0x2F]));
    let mut ldac_t = vec![PinT::set(State::High)];
    ldac_t.extend(ldac_pulse());
    let (mut spi, mut ldac) = (Spi::new(&spi_t), Pin::new(&ldac_t));
    let mut d = Ad5754::new(spi.clone(), ldac.clone(), NoopDelay::new(), 0).unwrap();
    d.init().unwrap();
    spi.done();
    ldac.done();
}

#[test]
fn a_wrong_range_readback_fails_init_before_power_up() {
    // SDO not connected reads all ones (or zeros): either way not the ±10 V code.
    for (rb, got) in [(0xFFFF, 0b111), (0x0000, 0)] {
        let (mut spi, mut ldac) = (
            Spi::new(&init_spi(2, rb)),
            Pin::new(&[PinT::set(State::High)]),
        );
        let mut d = Ad5754::new(spi.clone(), ldac.clone(), NoopDelay::new(), 2).unwrap();
        let e = d.init().unwrap_err();
        assert_eq!(e, Ad5754Error::RangeReadback(got));
        assert_eq!(e.kind(), ErrorKind::Bus);
        spi.done();
        ldac.done();
    }
}

#[test]
fn write_code_is_one_frame_then_an_ldac_pulse() {
    let mut t = write([0x01, 0x80, 0x00]); // DAC B, code −32768 (0x8000)
    t.extend(write([0x01, 0x7F, 0xFF]));
    let mut l = ldac_pulse();
    l.extend(ldac_pulse());
    let (mut spi, mut ldac) = (Spi::new(&t), Pin::new(&l));
    let mut d = Ad5754::new(spi.clone(), ldac.clone(), NoopDelay::new(), 1).unwrap();
    d.write_code(i16::MIN).unwrap();
    d.write_code(i16::MAX).unwrap();
    spi.done();
    ldac.done();
}

#[test]
fn a_channel_beyond_d_is_refused() {
    let (mut spi, mut ldac) = (Spi::new(&[]), Pin::new(&[]));
    let e = Ad5754::new(spi.clone(), ldac.clone(), NoopDelay::new(), 4)
        .err()
        .unwrap();
    assert_eq!(e, Ad5754Error::Channel(4));
    assert_eq!(e.kind(), ErrorKind::Other);
    spi.done();
    ldac.done();
}

struct BrokenSpi;
impl ErrorType for BrokenSpi {
    type Error = SpiKind;
}
impl SpiDevice for BrokenSpi {
    fn transaction(&mut self, _: &mut [Operation<'_, u8>]) -> Result<(), SpiKind> {
        Err(SpiKind::Overrun)
    }
}

#[test]
fn spi_and_ldac_errors_are_reported() {
    let mut ldac = Pin::new(&[PinT::set(State::High)]);
    let mut d = Ad5754::new(BrokenSpi, ldac.clone(), NoopDelay::new(), 0).unwrap();
    assert_eq!(d.init().unwrap_err(), Ad5754Error::Spi(SpiKind::Overrun));
    assert_eq!(d.write_code(1).unwrap_err().kind(), ErrorKind::Bus);
    ldac.done();

    let mut spi = Spi::new(&write([0x00, 0x00, 0x01]));
    let mut ldac =
        Pin::new(&[PinT::set(State::Low).with_error(MockError::Io(std::io::ErrorKind::Other))]);
    let mut d = Ad5754::new(spi.clone(), ldac.clone(), NoopDelay::new(), 0).unwrap();
    let e = d.write_code(1).unwrap_err();
    assert!(matches!(e, Ad5754Error::Pin(_)), "{e:?}");
    assert_eq!(e.kind(), ErrorKind::Bus);
    spi.done();
    ldac.done();
}
