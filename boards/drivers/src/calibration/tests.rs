use super::*;

#[test]
fn the_paper_default_maps_full_strokes_to_full_scale() {
    let c = ConverterCalibration::new(ConverterCalibrationConfig::paper_actuator()).unwrap();
    let k = c.config();
    assert_eq!((k.disp_channel, k.force_channel), (0, 1));
    assert!((k.disp.to_volts(25.4) - 10.0).abs() < 1e-12);
    assert!((k.force.to_volts(-31.14) + 10.0).abs() < 1e-12);
    assert!((k.command.to_volts(-25.4) + 10.0).abs() < 1e-12);
    assert!((k.disp.to_unit(5.0) - 12.7).abs() < 1e-12);
    assert!((k.force.to_unit(-2.5) + 31.14 / 4.0).abs() < 1e-12);
    assert!((k.disp.span_units() - 25.4).abs() < 1e-12);
    assert_eq!(c.channels_to_read(), 2);
}

#[test]
fn offsets_and_inverted_signs_apply() {
    let s = Scale {
        volts_per_unit: -0.5,
        offset_v: 0.25,
    };
    assert!((s.to_unit(s.to_volts(3.0)) - 3.0).abs() < 1e-12);
    assert!((s.to_volts(1.0) - (-0.25)).abs() < 1e-12);
    // The span is limited by the side the offset eats into: (10 − 0.25)/0.5 = 19.5.
    assert!((s.span_units() - 19.5).abs() < 1e-12);
}

#[test]
fn bad_calibrations_are_refused() {
    let ok = ConverterCalibrationConfig::paper_actuator();
    let bad_scale = Scale {
        volts_per_unit: 0.0,
        offset_v: 0.0,
    };
    let cases = [
        (
            ConverterCalibrationConfig {
                disp_channel: 8,
                ..ok
            },
            ConverterCalibrationError::Channel(8),
        ),
        (
            ConverterCalibrationConfig {
                force_channel: 0,
                ..ok
            },
            ConverterCalibrationError::SameChannel,
        ),
        (
            ConverterCalibrationConfig {
                disp: bad_scale,
                ..ok
            },
            ConverterCalibrationError::Scale("displacement"),
        ),
        (
            ConverterCalibrationConfig {
                force: Scale {
                    volts_per_unit: f64::NAN,
                    offset_v: 0.0,
                },
                ..ok
            },
            ConverterCalibrationError::Scale("force"),
        ),
        (
            ConverterCalibrationConfig {
                command: Scale {
                    volts_per_unit: 0.4,
                    offset_v: 10.0,
                },
                ..ok
            },
            ConverterCalibrationError::Offset("command"),
        ),
        (
            ConverterCalibrationConfig {
                command: Scale {
                    volts_per_unit: 0.4,
                    offset_v: f64::INFINITY,
                },
                ..ok
            },
            ConverterCalibrationError::Offset("command"),
        ),
    ];
    for (cfg, want) in cases {
        assert_eq!(ConverterCalibration::new(cfg), Err(want));
        assert!(!want.to_string().is_empty());
    }
}

#[test]
fn channels_to_read_reaches_the_higher_channel() {
    let c = ConverterCalibration::new(ConverterCalibrationConfig {
        disp_channel: 5,
        force_channel: 2,
        ..ConverterCalibrationConfig::paper_actuator()
    })
    .unwrap();
    assert_eq!(c.channels_to_read(), 6);
}
