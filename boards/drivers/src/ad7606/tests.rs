use super::*;
use embedded_hal::spi::{ErrorKind as SpiKind, ErrorType, Operation};
use embedded_hal_mock::eh1::delay::NoopDelay;
use embedded_hal_mock::eh1::digital::{Mock as Pin, State, Transaction as PinT};
use embedded_hal_mock::eh1::spi::{Mock as Spi, Transaction as SpiT};
use embedded_hal_mock::eh1::MockError;
use rths_core::hal::{Error as _, ErrorKind};

fn io_err() -> MockError {
    MockError::Io(std::io::ErrorKind::Other)
}

/// A read of `bytes` in one SPI transaction (CS low, read, CS high).
fn spi_read(bytes: Vec<u8>) -> Vec<SpiT<u8>> {
    vec![
        SpiT::transaction_start(),
        SpiT::read_vec(bytes),
        SpiT::transaction_end(),
    ]
}

type Adc = Ad7606<Spi<u8>, Pin, Pin, Pin, NoopDelay>;

fn adc(spi: &[SpiT<u8>], convst: &[PinT], busy: &[PinT], reset: &[PinT], n: u8) -> Adc {
    Ad7606::new(
        Spi::new(spi),
        Pin::new(convst),
        Pin::new(busy),
        Pin::new(reset),
        NoopDelay::new(),
        Ad7606Config::new(n),
    )
    .unwrap()
}

fn done(a: Adc) {
    let (mut s, mut c, mut b, mut r, _) = a.release();
    s.done();
    c.done();
    b.done();
    r.done();
}

fn convst_pulse() -> Vec<PinT> {
    vec![PinT::set(State::Low), PinT::set(State::High)]
}

#[test]
fn code_to_volts_is_the_data_sheet_transfer_function() {
    assert_eq!(code_to_volts(0), 0.0);
    assert_eq!(code_to_volts(i16::MIN), -10.0);
    assert_eq!(code_to_volts(16384), 5.0);
    assert_eq!(code_to_volts(-16384), -5.0);
    assert!((code_to_volts(i16::MAX) - (10.0 - 20.0 / 65536.0)).abs() < 1e-15);
    assert!((ADC_VOLTS_PER_CODE - 305.175_781_25e-6).abs() < 1e-15);
}

#[test]
fn init_pulses_reset_with_convst_idle_high() {
    let mut a = adc(
        &[],
        &[PinT::set(State::High)],
        &[],
        &[PinT::set(State::High), PinT::set(State::Low)],
        2,
    );
    a.init().unwrap();
    done(a);
}

#[test]
fn a_conversion_pulses_convst_waits_for_busy_and_reads_two_channels() {
    // V1 = 0x4000 (+5 V), V2 = 0xC000 (−5 V), big-endian.
    let mut a = adc(
        &spi_read(vec![0x40, 0x00, 0xC0, 0x00]),
        &convst_pulse(),
        &[
            PinT::get(State::Low),  // idle before the start
            PinT::get(State::High), // converting
            PinT::get(State::High), // still converting at the first poll
            PinT::get(State::Low),  // done
        ],
        &[],
        2,
    );
    let c = a.convert().unwrap();
    assert_eq!(c[0], 16384);
    assert_eq!(c[1], -16384);
    assert!(c[2..].iter().all(|x| *x == 0));
    done(a);
}

#[test]
fn all_eight_channels_come_out_in_order() {
    let words: Vec<i16> = vec![1, -1, 300, -300, i16::MAX, i16::MIN, 12345, -12345];
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_be_bytes()).collect();
    let mut a = adc(
        &spi_read(bytes),
        &convst_pulse(),
        &[
            PinT::get(State::Low),
            PinT::get(State::High),
            PinT::get(State::Low),
        ],
        &[],
        8,
    );
    assert_eq!(a.convert().unwrap().to_vec(), words);
    done(a);
}

#[test]
fn busy_high_before_the_start_is_busy_stuck() {
    let mut a = adc(&[], &[], &[PinT::get(State::High)], &[], 2);
    let e = a.convert().unwrap_err();
    assert_eq!(e, Ad7606Error::BusyStuck);
    assert_eq!(e.kind(), ErrorKind::Timeout);
    done(a);
}

#[test]
fn busy_that_never_rises_is_no_conversion() {
    let mut a = adc(
        &[],
        &convst_pulse(),
        &[PinT::get(State::Low), PinT::get(State::Low)],
        &[],
        2,
    );
    let e = a.convert().unwrap_err();
    assert_eq!(e, Ad7606Error::NoConversion);
    assert_eq!(e.kind(), ErrorKind::Bus);
    done(a);
}

#[test]
fn busy_that_never_falls_times_out_after_the_configured_polls() {
    let mut busy = vec![PinT::get(State::Low), PinT::get(State::High)];
    busy.extend(std::iter::repeat_n(PinT::get(State::High), 10));
    let mut a = adc(&[], &convst_pulse(), &busy, &[], 2);
    let e = a.convert().unwrap_err();
    assert_eq!(e, Ad7606Error::Timeout);
    assert_eq!(e.kind(), ErrorKind::Timeout);
    done(a);
}

#[test]
fn gpio_errors_are_pin_errors_of_kind_bus() {
    // BUSY read fails.
    let mut a = adc(
        &[],
        &[],
        &[PinT::get(State::Low).with_error(io_err())],
        &[],
        2,
    );
    let e = a.convert().unwrap_err();
    assert!(matches!(e, Ad7606Error::Pin(_)), "{e:?}");
    assert_eq!(e.kind(), ErrorKind::Bus);
    done(a);
    // CONVST write fails.
    let mut a = adc(
        &[],
        &[PinT::set(State::Low).with_error(io_err())],
        &[PinT::get(State::Low)],
        &[],
        2,
    );
    assert!(matches!(a.convert().unwrap_err(), Ad7606Error::Pin(_)));
    done(a);
    // RESET write fails in init.
    let mut a = adc(
        &[],
        &[PinT::set(State::High)],
        &[],
        &[PinT::set(State::High).with_error(io_err())],
        2,
    );
    assert!(matches!(a.init().unwrap_err(), Ad7606Error::Pin(_)));
    done(a);
}

/// An SPI device whose every transfer fails.
struct BrokenSpi;
impl ErrorType for BrokenSpi {
    type Error = SpiKind;
}
impl SpiDevice for BrokenSpi {
    fn transaction(&mut self, _: &mut [Operation<'_, u8>]) -> Result<(), SpiKind> {
        Err(SpiKind::ModeFault)
    }
}

#[test]
fn spi_errors_are_reported_with_their_kind() {
    let mut convst = Pin::new(&convst_pulse());
    let mut busy = Pin::new(&[
        PinT::get(State::Low),
        PinT::get(State::High),
        PinT::get(State::Low),
    ]);
    let mut reset = Pin::new(&[]);
    let mut a = Ad7606::new(
        BrokenSpi,
        convst.clone(),
        busy.clone(),
        reset.clone(),
        NoopDelay::new(),
        Ad7606Config::new(2),
    )
    .unwrap();
    let e = a.convert().unwrap_err();
    assert_eq!(e, Ad7606Error::Spi(SpiKind::ModeFault));
    assert_eq!(e.kind(), ErrorKind::Bus);
    convst.done();
    busy.done();
    reset.done();
}

#[test]
fn invalid_configurations_are_refused() {
    for cfg in [
        Ad7606Config::new(0),
        Ad7606Config::new(9),
        Ad7606Config {
            busy_timeout_polls: 0,
            ..Ad7606Config::new(2)
        },
    ] {
        let mut pins = [Pin::new(&[]), Pin::new(&[]), Pin::new(&[])];
        let mut spi = Spi::new(&[]);
        let r = Ad7606::new(
            spi.clone(),
            pins[0].clone(),
            pins[1].clone(),
            pins[2].clone(),
            NoopDelay::new(),
            cfg,
        );
        assert_eq!(r.err().map(|e| e.kind()), Some(ErrorKind::Other));
        spi.done();
        pins.iter_mut().for_each(|p| p.done());
    }
}
