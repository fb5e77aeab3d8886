//! Simulated switches: an input pin driven by where an axis physically is.
//!
//! A switch attached to an axis ([`Hub::attach_switch`](crate::Hub::attach_switch))
//! reads its active level while the axis's physical position (the signed
//! count of its own step edges since it started, whatever set_position or
//! homing did) lies in its active range. The axis's cog works the level
//! out right after each step edge, before anything else happens, so the
//! axis sees the switch on the exact step that changed it, in virtual and
//! in real time alike.
//!
//! With [`Bounce`], the level chatters within `steps` steps inside each
//! finite end of the range: the end step itself always reads active (the
//! first contact), the steps after it read active or not as a seeded hash
//! of their distance says. The chatter is a function of the position, so
//! it is the same in every run and at every speed.

use std::ops::RangeInclusive;

/// Contact bounce of a simulated switch.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Bounce {
    /// How many steps past each end of the active range chatter (0: none).
    pub steps: u32,
    /// The seed of the chatter pattern.
    pub seed: u64,
}

/// A switch attached to an axis.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Switch {
    /// The input pin it drives.
    pub pin: u8,
    /// The physical positions at which it is pressed.
    pub active: RangeInclusive<i64>,
    /// The level it reads while pressed.
    pub active_level: bool,
    /// Its contact bounce.
    pub bounce: Bounce,
}

impl Switch {
    /// Whether the switch is pressed at physical position `physical`.
    pub fn pressed_at(&self, physical: i64) -> bool {
        let (low, high) = (*self.active.start(), *self.active.end());
        if physical < low || physical > high {
            return false;
        }
        let bounce = u64::from(self.bounce.steps);
        if bounce == 0 {
            return true;
        }
        // Distance inside the range from its nearest finite end.
        let from_low = (low != i64::MIN).then(|| physical.abs_diff(low));
        let from_high = (high != i64::MAX).then(|| physical.abs_diff(high));
        let distance = match (from_low, from_high) {
            (Some(a), Some(b)) => a.min(b),
            (Some(a), None) | (None, Some(a)) => a,
            (None, None) => return true,
        };
        if distance == 0 || distance > bounce {
            return true;
        }
        chatter(
            self.bounce.seed ^ u64::from(self.pin).rotate_left(56),
            distance,
        ) & 1
            == 1
    }

    /// The pin's level at physical position `physical`.
    pub fn level_at(&self, physical: i64) -> bool {
        self.pressed_at(physical) == self.active_level
    }
}

/// A home switch and two hard limits on one axis, as the demo and the
/// board simulator fit them ([`Hub::fit_demo_switches`](crate::Hub::fit_demo_switches)).
/// Axis `index` (0 to 7) has, all active high:
///
/// | switch | pin | pressed at physical position |
/// |---|---|---|
/// | home | 40 + index | ≤ −2,000 (with 3 steps of bounce) |
/// | min limit | 48 + index | ≤ −6,000 |
/// | max limit | 56 + index | ≥ 400,000 |
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DemoSwitches {
    /// The home switch's pin.
    pub home_pin: u8,
    /// The min limit's pin.
    pub min_pin: u8,
    /// The max limit's pin.
    pub max_pin: u8,
    /// The home switch is pressed at and below this physical position.
    pub home_at: i64,
    /// The min limit is pressed at and below this physical position.
    pub min_at: i64,
    /// The max limit is pressed at and above this physical position.
    pub max_at: i64,
}

impl DemoSwitches {
    /// The switches of axis `index`, or `None` past axis 7.
    pub fn for_axis(index: usize) -> Option<Self> {
        let index = u8::try_from(index).ok().filter(|index| *index < 8)?;
        Some(Self {
            home_pin: 40 + index,
            min_pin: 48 + index,
            max_pin: 56 + index,
            home_at: -2_000,
            min_at: -6_000,
            max_at: 400_000,
        })
    }

    /// Homing onto the home switch (reverse, the switch point becomes 0).
    pub fn home_config(&self) -> cogstep_motion::axis::HomeConfig {
        cogstep_motion::axis::HomeConfig {
            switch_pin: self.home_pin,
            active_level: true,
            direction: cogstep_motion::axis::Direction::Reverse,
            seek_speed: 8_000,
            latch_speed: 500,
            backoff_steps: 200,
            max_travel: 500_000,
            set_position: 0,
        }
    }
}

/// SplitMix64 of `seed` and `distance`: the chatter pattern.
fn chatter(seed: u64, distance: u64) -> u64 {
    let mut z = seed.wrapping_add(distance.wrapping_mul(0x9E37_79B9_7F4A_7C15));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn switch(active: RangeInclusive<i64>, steps: u32) -> Switch {
        Switch {
            pin: 10,
            active,
            active_level: true,
            bounce: Bounce { steps, seed: 7 },
        }
    }

    #[test]
    fn a_clean_switch_reads_its_range() {
        let sw = switch(i64::MIN..=-3_217, 0);
        assert!(sw.level_at(-3_217) && sw.level_at(i64::MIN));
        assert!(!sw.level_at(-3_216));
        let low = Switch {
            active_level: false,
            ..sw
        };
        assert!(!low.level_at(-4_000) && low.level_at(0));
    }

    #[test]
    fn bounce_chatters_only_just_inside_the_ends() {
        let sw = switch(100..=i64::MAX, 8);
        assert!(sw.pressed_at(100), "the first contact always reads pressed");
        assert!(!sw.pressed_at(99));
        assert!((109..1_000).all(|p| sw.pressed_at(p)));
        let chattering = (101..=108).filter(|p| !sw.pressed_at(*p)).count();
        assert!(chattering > 0 && chattering < 8, "{chattering}");
    }
}
