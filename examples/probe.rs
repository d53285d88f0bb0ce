use rths::analysis::{pure_response, Method};
use rths::motion::GroundMotion;
use rths::scenario::*;
use rths_core::params::{Prototype, DT_S};
use rths_hal_sim::{Preset, Specimen};
fn main() {
    let ag = GroundMotion::el_centro().resample_mm_s2(DT_S);
    let r = pure_response(&Prototype::paper(), &ag, DT_S, Method::Chang).unwrap();
    for id in [ScenarioId::FePure, ScenarioId::FeOffline, ScenarioId::FeOnline, ScenarioId::FeOnlineAts] {
        let t = std::time::Instant::now();
        let run = run(&ScenarioSetup { id, ground_accel_mm_s2: &ag, reference_mm: &r.brace_disp_mm,
            rig: rig_config(Preset::UnrCompact, Specimen::Linear, 1.0, 1), stiffness_factor: 1.0, lr: None, rnn: None, delay_steps: 28 }).unwrap();
        println!("{} {:?}", serde_json::to_string(&run.report).unwrap(), t.elapsed());
    }
}
