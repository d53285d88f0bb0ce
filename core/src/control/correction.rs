//! The force correction of a hybrid test: the measured force brought to the displacement the
//! analytical part asked for, with the identified specimen (docs/design.md §5.3, at the rig).

use crate::params::ParamError;

/// `F̃ = F_m + k̂·(d̂ − x_m) − m̂·d̂'' − ĉ·d̂'`, d̂ the displacement the rig was to be at (the
/// target in force at the tick), its derivatives by central differences one tick back, all at
/// the rig (specimen units). The spring term removes the rig's tracking error from the force; the
/// mass and damping terms remove what the rig's specimen has and the analytical part's (a spring)
/// does not. Validated: k̂, ĉ, m̂ finite and ≥ 0, the step finite and > 0.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceCorrection {
    k_kn_per_mm: f64,
    c_kn_s_per_mm: f64,
    m_kn_s2_per_mm: f64,
    dt_s: f64,
}

impl ForceCorrection {
    /// No correction: the measured force as is (a controller given it adds no term at all).
    pub const NONE: Self = Self {
        k_kn_per_mm: 0.0,
        c_kn_s_per_mm: 0.0,
        m_kn_s2_per_mm: 0.0,
        dt_s: 1.0,
    };

    /// From identified values k̂ (kN/mm), ĉ (kN·s/mm), m̂ (kN·s²/mm) at the rig, for a controller
    /// ticking every `dt_s`: refused unless k̂, ĉ, m̂ are finite and ≥ 0 and `dt_s` finite > 0.
    pub fn new(
        k_kn_per_mm: f64,
        c_kn_s_per_mm: f64,
        m_kn_s2_per_mm: f64,
        dt_s: f64,
    ) -> Result<Self, ParamError> {
        for (what, v) in [
            ("identified specimen stiffness (finite, ≥ 0)", k_kn_per_mm),
            ("identified specimen damping (finite, ≥ 0)", c_kn_s_per_mm),
            ("identified specimen mass (finite, ≥ 0)", m_kn_s2_per_mm),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(ParamError::OutOfRange(what));
            }
        }
        if !(dt_s.is_finite() && dt_s > 0.0) {
            return Err(ParamError::OutOfRange(
                "force correction step (finite, > 0)",
            ));
        }
        Ok(Self {
            k_kn_per_mm,
            c_kn_s_per_mm,
            m_kn_s2_per_mm,
            dt_s,
        })
    }

    /// No term at all (k̂ = ĉ = m̂ = 0).
    pub fn is_none(&self) -> bool {
        self.k_kn_per_mm == 0.0 && self.c_kn_s_per_mm == 0.0 && self.m_kn_s2_per_mm == 0.0
    }

    /// k̂, kN/mm.
    pub fn k_kn_per_mm(&self) -> f64 {
        self.k_kn_per_mm
    }
    /// ĉ, kN·s/mm.
    pub fn c_kn_s_per_mm(&self) -> f64 {
        self.c_kn_s_per_mm
    }
    /// m̂, kN·s²/mm.
    pub fn m_kn_s2_per_mm(&self) -> f64 {
        self.m_kn_s2_per_mm
    }

    /// `F̃` from the measured force and displacement and the rig's targets `d = [d̂_k, d̂_{k−1},
    /// d̂_{k−2}]` (mm).
    #[inline]
    pub fn force_kn(&self, force_kn: f64, disp_mm: f64, d: [f64; 3]) -> f64 {
        let dt_s = self.dt_s;
        let accel = (d[0] - 2.0 * d[1] + d[2]) / (dt_s * dt_s);
        let vel = (d[0] - d[2]) / (2.0 * dt_s);
        force_kn + self.k_kn_per_mm * (d[0] - disp_mm)
            - self.m_kn_s2_per_mm * accel
            - self.c_kn_s_per_mm * vel
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refuses_bad_values_and_corrects_by_the_formula() {
        assert!(ForceCorrection::new(f64::NAN, 0.0, 0.0, 1e-3).is_err());
        assert!(ForceCorrection::new(1.0, -1.0, 0.0, 1e-3).is_err());
        assert!(ForceCorrection::new(1.0, 0.0, f64::INFINITY, 1e-3).is_err());
        assert!(ForceCorrection::new(1.0, 0.0, 0.0, 0.0).is_err());
        assert!(ForceCorrection::NONE.is_none());
        let c = ForceCorrection::new(2.0, 0.5, 0.25, 0.5).unwrap();
        assert!(!c.is_none());
        // d̂ = [3, 2, 0]: d̂'' = (3 − 4 + 0)/0.25 = −4, d̂' = 3/1 = 3.
        let f = c.force_kn(10.0, 1.0, [3.0, 2.0, 0.0]);
        assert!((f - (10.0 + 2.0 * 2.0 + 0.25 * 4.0 - 0.5 * 3.0)).abs() < 1e-12);
    }
}
