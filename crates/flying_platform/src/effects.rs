//! Physical effects that can be switched on and off, each declaring its parameters.
//!
//! The low-complexity model of the paper is the model with no effect enabled; the paper's
//! augmented model is `momentum_drag + fan_gyroscopic + input_delay` (spec §6.7).

use crate::error::{Error, Result};

/// Declaration of one named parameter: unit, bounds and default (spec §7.1 and §10).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamSpec {
    /// Parameter name, unique across all effects.
    pub name: &'static str,
    /// SI unit.
    pub unit: &'static str,
    /// Lower bound (inclusive).
    pub lower: f64,
    /// Upper bound (inclusive).
    pub upper: f64,
    /// Default value (the paper's appendix where it has one).
    pub default: f64,
    /// What the parameter means.
    pub description: &'static str,
}

impl ParamSpec {
    /// Checks `value` against the bounds, naming the parameter on failure.
    pub fn check(&self, value: f64) -> Result<()> {
        if value.is_finite() && value >= self.lower && value <= self.upper {
            Ok(())
        } else {
            Err(Error::OutOfBounds {
                name: self.name.to_string(),
                value,
                lower: self.lower,
                upper: self.upper,
            })
        }
    }
}

const MOMENTUM_DRAG: [ParamSpec; 6] = [
    ParamSpec {
        name: "c_alpha1",
        unit: "N s/m",
        lower: 0.0,
        upper: 50.0,
        default: 2.388,
        description: "horizontal momentum-drag coefficient per unit",
    },
    ParamSpec {
        name: "c_alpha2",
        unit: "N s/m",
        lower: 0.0,
        upper: 50.0,
        default: 4.939,
        description: "vertical momentum-drag coefficient per unit",
    },
    ParamSpec {
        name: "l_alpha1",
        unit: "m",
        lower: -1.0,
        upper: 1.0,
        default: 0.242,
        description: "lever arm of the drag force caused by roll/pitch rates",
    },
    ParamSpec {
        name: "l_alpha2",
        unit: "m",
        lower: -1.0,
        upper: 1.0,
        default: -0.138,
        description: "lever arm of the drag moment caused by horizontal velocity",
    },
    ParamSpec {
        name: "l_alpha3",
        unit: "m^2",
        lower: -0.5,
        upper: 0.5,
        default: -0.0084,
        description: "roll/pitch rate drag moment (negative = anti-damping)",
    },
    ParamSpec {
        name: "l_alpha4",
        unit: "m^2",
        lower: 0.0,
        upper: 5.0,
        default: 0.362 * 0.11,
        description: "yaw rate drag moment (Table 3 gives l_alpha4/I3 = 0.362 1/kg, I3 = 0.11)",
    },
];

const FAN_GYROSCOPIC: [ParamSpec; 1] = [ParamSpec {
    name: "c_omega_t0",
    unit: "kg m^2/s",
    lower: -0.2,
    upper: 0.2,
    default: 0.018,
    description: "angular momentum C omega_T0 of one fan rotor at hover (sign = spin direction)",
}];

const ACTUATOR_LAG: [ParamSpec; 1] = [ParamSpec {
    name: "tau",
    unit: "s",
    lower: 1e-4,
    upper: 0.5,
    default: 0.01,
    description: "first-order time constant from thrust command to thrust, all 9 inputs",
}];

const INPUT_DELAY: [ParamSpec; 1] = [ParamSpec {
    name: "td",
    unit: "s",
    lower: 0.0,
    upper: 0.2,
    default: 0.045,
    description: "transport delay of all inputs (sample-and-hold and latency)",
}];

/// The four switchable physical effects, in their canonical order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Effect {
    /// Velocity-proportional forces and moments of the ducts (spec §6.7).
    MomentumDrag,
    /// Gyroscopic torque of three fans spinning the same way.
    FanGyroscopic,
    /// First-order lag from thrust command to thrust.
    ActuatorLag,
    /// Pure input delay `e^{-s Td}`.
    InputDelay,
}

impl Effect {
    /// All effects in canonical order.
    pub const ALL: [Effect; 4] = [
        Effect::MomentumDrag,
        Effect::FanGyroscopic,
        Effect::ActuatorLag,
        Effect::InputDelay,
    ];

    /// The effect's name: `momentum_drag`, `fan_gyroscopic`, `actuator_lag`, `input_delay`.
    pub fn name(self) -> &'static str {
        match self {
            Effect::MomentumDrag => "momentum_drag",
            Effect::FanGyroscopic => "fan_gyroscopic",
            Effect::ActuatorLag => "actuator_lag",
            Effect::InputDelay => "input_delay",
        }
    }

    /// Parses a name as returned by [`Effect::name`].
    ///
    /// ```
    /// use flying_platform::Effect;
    /// assert_eq!(Effect::from_name("momentum_drag").unwrap(), Effect::MomentumDrag);
    /// assert!(Effect::from_name("ground_effect").is_err());
    /// ```
    pub fn from_name(name: &str) -> Result<Self> {
        Self::ALL
            .into_iter()
            .find(|e| e.name() == name)
            .ok_or_else(|| Error::UnknownEffect(name.to_string()))
    }

    /// The parameters this effect declares.
    pub fn params(self) -> &'static [ParamSpec] {
        match self {
            Effect::MomentumDrag => &MOMENTUM_DRAG,
            Effect::FanGyroscopic => &FAN_GYROSCOPIC,
            Effect::ActuatorLag => &ACTUATOR_LAG,
            Effect::InputDelay => &INPUT_DELAY,
        }
    }

    /// The default parameter values of this effect.
    pub fn defaults(self) -> Vec<f64> {
        self.params().iter().map(|p| p.default).collect()
    }

    fn index(self) -> usize {
        self as usize
    }
}

impl core::fmt::Display for Effect {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

impl core::str::FromStr for Effect {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        Self::from_name(s)
    }
}

/// Momentum-drag parameters (spec §6.7), SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MomentumDrag {
    /// Horizontal coefficient c_alpha1, N s/m.
    pub c_alpha1: f64,
    /// Vertical coefficient c_alpha2, N s/m.
    pub c_alpha2: f64,
    /// Force-from-rate lever arm l_alpha1, m.
    pub l_alpha1: f64,
    /// Moment-from-velocity lever arm l_alpha2, m.
    pub l_alpha2: f64,
    /// Roll/pitch rate moment l_alpha3, m².
    pub l_alpha3: f64,
    /// Yaw rate moment l_alpha4, m².
    pub l_alpha4: f64,
}

impl MomentumDrag {
    /// The "point model" (spec §12.2): each unit's drag `-C_alpha (v + w x r_P)` acts at one
    /// point `P` at `height` above the CoG (m) and horizontal `radius` (m), which fixes
    /// `l_alpha1 = l_alpha2 = height`, `l_alpha3 = height² + (c_alpha2/c_alpha1) radius²/2` and
    /// `l_alpha4 = (c_alpha1/c_alpha2) radius²`.
    pub fn point_model(c_alpha1: f64, c_alpha2: f64, height: f64, radius: f64) -> Result<Self> {
        for (name, v) in [("c_alpha1", c_alpha1), ("c_alpha2", c_alpha2)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::Invalid {
                    name,
                    reason: format!("point model needs > 0, got {v}"),
                });
            }
        }
        Ok(Self {
            c_alpha1,
            c_alpha2,
            l_alpha1: height,
            l_alpha2: height,
            l_alpha3: height * height + c_alpha2 / c_alpha1 * radius * radius / 2.0,
            l_alpha4: c_alpha1 / c_alpha2 * radius * radius,
        })
    }

    /// The parameters in flat-vector order (`c_alpha1 .. l_alpha4`).
    pub fn to_vector(&self) -> [f64; 6] {
        [
            self.c_alpha1,
            self.c_alpha2,
            self.l_alpha1,
            self.l_alpha2,
            self.l_alpha3,
            self.l_alpha4,
        ]
    }
}

/// The set of enabled effects with their parameter values.
///
/// ```
/// use flying_platform::{Effect, EffectSet};
/// let set = EffectSet::augmented();
/// assert!(set.contains(Effect::MomentumDrag) && !set.contains(Effect::ActuatorLag));
/// assert_eq!(set.momentum_drag().unwrap().c_alpha1, 2.388);
/// ```
#[derive(Debug, Clone, PartialEq, Default)]
pub struct EffectSet {
    values: [Option<Vec<f64>>; 4],
}

impl EffectSet {
    /// No effect: the low-complexity model.
    pub fn none() -> Self {
        Self::default()
    }

    /// The paper's augmented model: momentum drag, fan gyroscopic torque and input delay.
    pub fn augmented() -> Self {
        Self::from_effects(&[
            Effect::MomentumDrag,
            Effect::FanGyroscopic,
            Effect::InputDelay,
        ])
    }

    /// The given effects with default parameters.
    pub fn from_effects(effects: &[Effect]) -> Self {
        let mut s = Self::none();
        for &e in effects {
            s.enable(e);
        }
        s
    }

    /// Parses a comma-separated list of effect names (empty string = no effect).
    pub fn parse(list: &str) -> Result<Self> {
        let mut s = Self::none();
        for name in list.split(',').map(str::trim).filter(|n| !n.is_empty()) {
            s.enable(Effect::from_name(name)?);
        }
        Ok(s)
    }

    /// Enables an effect with its default parameters (keeps current values if already on).
    pub fn enable(&mut self, effect: Effect) {
        let slot = &mut self.values[effect.index()];
        if slot.is_none() {
            *slot = Some(effect.defaults());
        }
    }

    /// Enables an effect with the given parameter values (checked against the bounds).
    pub fn enable_with(&mut self, effect: Effect, values: &[f64]) -> Result<()> {
        check_values(effect, values)?;
        self.values[effect.index()] = Some(values.to_vec());
        Ok(())
    }

    /// Disables an effect.
    pub fn disable(&mut self, effect: Effect) {
        self.values[effect.index()] = None;
    }

    /// Whether the effect is enabled.
    pub fn contains(&self, effect: Effect) -> bool {
        self.values[effect.index()].is_some()
    }

    /// Enabled effects in canonical order.
    pub fn enabled(&self) -> Vec<Effect> {
        Effect::ALL
            .into_iter()
            .filter(|&e| self.contains(e))
            .collect()
    }

    /// Parameter values of an enabled effect.
    pub fn values(&self, effect: Effect) -> Option<&[f64]> {
        self.values[effect.index()].as_deref()
    }

    /// Declarations of all parameters of the enabled effects, in flat-vector order.
    pub fn param_specs(&self) -> Vec<ParamSpec> {
        self.enabled()
            .into_iter()
            .flat_map(|e| e.params().iter().copied())
            .collect()
    }

    /// Names of the flat parameter vector.
    pub fn param_names(&self) -> Vec<&'static str> {
        self.param_specs().iter().map(|p| p.name).collect()
    }

    /// The flat parameter vector of the enabled effects (canonical effect order).
    pub fn to_vector(&self) -> Vec<f64> {
        self.values.iter().flatten().flatten().copied().collect()
    }

    /// Sets the flat parameter vector of the enabled effects; checks length and bounds.
    pub fn set_vector(&mut self, theta: &[f64]) -> Result<()> {
        let expected = self.param_specs().len();
        if theta.len() != expected {
            return Err(Error::Length {
                what: "effect parameter vector",
                got: theta.len(),
                expected,
            });
        }
        let mut offset = 0;
        for e in self.enabled() {
            let n = e.params().len();
            check_values(e, &theta[offset..offset + n])?;
            offset += n;
        }
        let mut offset = 0;
        for e in self.enabled() {
            let n = e.params().len();
            self.values[e.index()] = Some(theta[offset..offset + n].to_vec());
            offset += n;
        }
        Ok(())
    }

    /// Value of a named parameter of an enabled effect.
    pub fn get(&self, name: &str) -> Result<f64> {
        let (e, i) = self.locate(name)?;
        self.values(e)
            .and_then(|v| v.get(i).copied())
            .ok_or_else(|| Error::UnknownParameter(name.to_string()))
    }

    /// Sets a named parameter of an enabled effect (checked against its bounds).
    pub fn set(&mut self, name: &str, value: f64) -> Result<()> {
        let (e, i) = self.locate(name)?;
        e.params()[i].check(value)?;
        match self.values[e.index()].as_mut().and_then(|v| v.get_mut(i)) {
            Some(slot) => {
                *slot = value;
                Ok(())
            }
            None => Err(Error::UnknownParameter(name.to_string())),
        }
    }

    fn locate(&self, name: &str) -> Result<(Effect, usize)> {
        self.enabled()
            .into_iter()
            .find_map(|e| {
                e.params()
                    .iter()
                    .position(|p| p.name == name)
                    .map(|i| (e, i))
            })
            .ok_or_else(|| Error::UnknownParameter(name.to_string()))
    }

    /// Momentum-drag parameters if enabled.
    pub fn momentum_drag(&self) -> Option<MomentumDrag> {
        self.values(Effect::MomentumDrag).map(|v| MomentumDrag {
            c_alpha1: v[0],
            c_alpha2: v[1],
            l_alpha1: v[2],
            l_alpha2: v[3],
            l_alpha3: v[4],
            l_alpha4: v[5],
        })
    }

    /// Fan angular momentum `C omega_T0` (kg m²/s) if the gyroscopic effect is enabled.
    pub fn fan_momentum(&self) -> Option<f64> {
        self.values(Effect::FanGyroscopic).map(|v| v[0])
    }

    /// Actuator time constant (s) if the lag is enabled.
    pub fn actuator_tau(&self) -> Option<f64> {
        self.values(Effect::ActuatorLag).map(|v| v[0])
    }

    /// Input delay (s); 0 when the delay is disabled.
    pub fn delay(&self) -> f64 {
        self.values(Effect::InputDelay).map_or(0.0, |v| v[0])
    }
}

fn check_values(effect: Effect, values: &[f64]) -> Result<()> {
    let specs = effect.params();
    if values.len() != specs.len() {
        return Err(Error::Length {
            what: effect.name(),
            got: values.len(),
            expected: specs.len(),
        });
    }
    specs.iter().zip(values).try_for_each(|(s, &v)| s.check(v))
}
