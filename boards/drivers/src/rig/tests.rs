use super::*;
use crate::ad5754::Ad5754;
use crate::ad7606::{Ad7606, Ad7606Config};
use crate::calibration::{ConverterCalibrationConfig, Scale};
use embedded_hal_mock::eh1::delay::NoopDelay;
use embedded_hal_mock::eh1::digital::{Mock as Pin, State, Transaction as PinT};
use embedded_hal_mock::eh1::spi::{Mock as Spi, Transaction as SpiT};
use embedded_hal_mock::eh1::MockError;
use rths_core::hal::Error as _;
use rths_core::supervisor::{FaultReason, Limits, State as SState, Supervisor};

type TestRig = Rig<Spi<u8>, Pin, Pin, Pin, NoopDelay, Spi<u8>, Pin, NoopDelay>;

struct Mocks {
    adc_spi: Spi<u8>,
    convst: Pin,
    busy: Pin,
    reset: Pin,
    dac_spi: Spi<u8>,
    ldac: Pin,
}

impl Mocks {
    fn done(mut self) {
        self.adc_spi.done();
        self.convst.done();
        self.busy.done();
        self.reset.done();
        self.dac_spi.done();
        self.ldac.done();
    }
}

fn rig(
    cal: ConverterCalibrationConfig,
    adc_spi: &[SpiT<u8>],
    conversions: usize,
    dac_spi: &[SpiT<u8>],
    ldac_pulses: usize,
) -> (TestRig, Mocks) {
    let cal = ConverterCalibration::new(cal).unwrap();
    let mut conv = Vec::new();
    let mut busy = Vec::new();
    for _ in 0..conversions {
        conv.extend([PinT::set(State::Low), PinT::set(State::High)]);
        busy.extend([
            PinT::get(State::Low),
            PinT::get(State::High),
            PinT::get(State::Low),
        ]);
    }
    let mut l = Vec::new();
    for _ in 0..ldac_pulses {
        l.extend([PinT::set(State::Low), PinT::set(State::High)]);
    }
    let m = Mocks {
        adc_spi: Spi::new(adc_spi),
        convst: Pin::new(&conv),
        busy: Pin::new(&busy),
        reset: Pin::new(&[]),
        dac_spi: Spi::new(dac_spi),
        ldac: Pin::new(&l),
    };
    let adc = Ad7606::new(
        m.adc_spi.clone(),
        m.convst.clone(),
        m.busy.clone(),
        m.reset.clone(),
        NoopDelay::new(),
        Ad7606Config::new(cal.channels_to_read() as u8),
    )
    .unwrap();
    let dac = Ad5754::new(m.dac_spi.clone(), m.ldac.clone(), NoopDelay::new(), 0).unwrap();
    (Rig::new(adc, dac, cal), m)
}

fn read(bytes: Vec<u8>) -> Vec<SpiT<u8>> {
    vec![
        SpiT::transaction_start(),
        SpiT::read_vec(bytes),
        SpiT::transaction_end(),
    ]
}

fn dac_write(code: i16) -> Vec<SpiT<u8>> {
    let [hi, lo] = code.to_be_bytes();
    vec![
        SpiT::transaction_start(),
        SpiT::write_vec(vec![0x00, hi, lo]),
        SpiT::transaction_end(),
    ]
}

#[test]
fn read_converts_codes_to_mm_and_kn_through_the_calibration() {
    // V1 = +5 V → 12.7 mm; V2 = −2.5 V → −7.785 kN (paper default).
    let (mut r, m) = rig(
        ConverterCalibrationConfig::paper_actuator(),
        &read(vec![0x40, 0x00, 0xE0, 0x00]),
        1,
        &[],
        0,
    );
    let s = r.read().unwrap();
    assert!((s.disp_mm - 12.7).abs() < 1e-12, "{s:?}");
    assert!((s.force_kn + 31.14 / 4.0).abs() < 1e-12, "{s:?}");
    drop(r);
    m.done();
}

#[test]
fn channel_assignment_and_offsets_come_from_the_calibration() {
    // Force on V1, displacement on V3 with 1 V/mm and a +0.5 V offset.
    let cal = ConverterCalibrationConfig {
        disp_channel: 2,
        force_channel: 0,
        disp: Scale {
            volts_per_unit: 1.0,
            offset_v: 0.5,
        },
        ..ConverterCalibrationConfig::paper_actuator()
    };
    // V1 = 0 V, V2 = anything, V3 = +2.5 V → (2.5 − 0.5)/1 = 2 mm.
    let (mut r, m) = rig(
        cal,
        &read(vec![0x00, 0x00, 0x12, 0x34, 0x20, 0x00]),
        1,
        &[],
        0,
    );
    let s = r.read().unwrap();
    assert!((s.disp_mm - 2.0).abs() < 1e-12, "{s:?}");
    assert_eq!(s.force_kn, 0.0);
    drop(r);
    m.done();
}

#[test]
fn command_writes_the_calibrated_code_and_latches_it() {
    // 12.7 mm → +5 V → 16384; −25.4 mm → −10 V → −32768.
    let mut t = dac_write(16384);
    t.extend(dac_write(i16::MIN));
    let (mut r, m) = rig(ConverterCalibrationConfig::paper_actuator(), &[], 0, &t, 2);
    r.command(12.7).unwrap();
    assert_eq!(r.last_code(), 16384);
    r.command(-25.4).unwrap();
    assert_eq!(r.last_code(), i16::MIN);
    drop(r);
    m.done();
}

#[test]
fn a_command_beyond_full_scale_is_clipped_written_and_reported() {
    let (mut r, m) = rig(
        ConverterCalibrationConfig::paper_actuator(),
        &[],
        0,
        &dac_write(i16::MAX),
        1,
    );
    let e = r.command(30.0).unwrap_err();
    assert_eq!(e, RigError::OutOfRange);
    assert_eq!(e.kind(), ErrorKind::OutOfRange);
    assert_eq!(r.last_code(), i16::MAX);
    drop(r);
    m.done();
}

#[test]
fn a_non_finite_command_is_refused_and_nothing_is_written() {
    let (mut r, m) = rig(ConverterCalibrationConfig::paper_actuator(), &[], 0, &[], 0);
    for x in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let e = r.command(x).unwrap_err();
        assert_eq!(e.kind(), ErrorKind::NotFinite);
    }
    drop(r);
    m.done();
}

#[test]
fn adc_and_dac_failures_keep_their_kind() {
    // BUSY stuck high before the conversion.
    let cal = ConverterCalibration::new(ConverterCalibrationConfig::paper_actuator()).unwrap();
    let mut busy = Pin::new(&[PinT::get(State::High)]);
    let mut others = [Spi::new(&[])];
    let mut pins = [Pin::new(&[]), Pin::new(&[])];
    let adc = Ad7606::new(
        others[0].clone(),
        pins[0].clone(),
        busy.clone(),
        pins[1].clone(),
        NoopDelay::new(),
        Ad7606Config::new(2),
    )
    .unwrap();
    let mut ldac =
        Pin::new(&[PinT::set(State::Low).with_error(MockError::Io(std::io::ErrorKind::Other))]);
    let mut dac_spi = Spi::new(&dac_write(0));
    let dac = Ad5754::new(dac_spi.clone(), ldac.clone(), NoopDelay::new(), 0).unwrap();
    let mut r = Rig::new(adc, dac, cal);
    let e = r.read().unwrap_err();
    assert!(matches!(e, RigError::Adc(_)));
    assert_eq!(e.kind(), ErrorKind::Timeout);
    let e = r.command(0.0).unwrap_err();
    assert!(matches!(e, RigError::Dac(_)));
    assert_eq!(e.kind(), ErrorKind::Bus);
    busy.done();
    ldac.done();
    dac_spi.done();
    others.iter_mut().for_each(|m| m.done());
    pins.iter_mut().for_each(|m| m.done());
}

#[test]
fn the_estop_trips_the_supervisor_which_then_ramps() {
    let mut sup = Supervisor::new(Limits::paper_actuator());
    sup.arm().unwrap();
    sup.start().unwrap();
    // Fail-safe wiring: low = closed contact = fine; high = pressed or broken; a read error = stop.
    let mut pin = Pin::new(&[
        PinT::get(State::Low),
        PinT::get(State::High),
        PinT::get(State::Low).with_error(MockError::Io(std::io::ErrorKind::Other)),
    ]);
    let mut e = EStop::new(pin.clone(), ActiveLevel::High);
    assert!(!check_estop(&mut e, &mut sup));
    assert_eq!(sup.state(), SState::Running);
    assert!(check_estop(&mut e, &mut sup));
    assert_eq!(sup.state(), SState::Fault(FaultReason::EmergencyStop));
    assert!(e.is_active(), "an unreadable E-stop counts as pressed");
    pin.done();

    let mut pin = Pin::new(&[PinT::get(State::Low), PinT::get(State::High)]);
    let mut e = EStop::new(pin.clone(), ActiveLevel::Low);
    assert!(e.is_active());
    assert!(!e.is_active());
    pin.done();
}
