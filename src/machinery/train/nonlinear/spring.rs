//! The latent springs of the nonlinear metamodel: their law family and θ's numbers per spring,
//! which the per-spring fit (stage 1) and the whole-model search (stage 2) share.

/// θ's numbers per spring (yield force, post-yield ratio, exponent, γ, and one unused since the
/// spring's `k0` is its story's elastic stiffness: [`super::stage1::spring_spec`]) and per mode
/// (frequency and damping scale).
pub(crate) const PER_SPRING: usize = 5;

/// The law family of the latent springs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SpringLaw {
    /// Bilinear kinematic hardening (sharp yield; cheap: a clamp per tick).
    Bilinear,
    /// Bouc–Wen (smooth knee; exponent and shape learned too).
    BoucWen,
}

impl SpringLaw {
    /// The model file's name of the law.
    pub fn name(self) -> &'static str {
        match self {
            SpringLaw::Bilinear => "bilinear",
            SpringLaw::BoucWen => "bouc-wen",
        }
    }
}
