//! One value per leg of the trainer, without allocating: a trainer has one leg (the
//! exoskeleton's leg on a fixed pelvis, or on a treadmill with a virtual other leg) or two
//! (a bilateral trainer, the second leg half a stride later). Everything that is one
//! leg's (its angles, its four pressures, its controllers' output, its foot's contact) is
//! written once and held in a [`PerLeg`].
use pma_control::supervisor::Channels;

/// Most legs a trainer has.
pub const MAX_LEGS: usize = 2;

/// The legs' names, in index order: the first leg is the right one (a one-leg trainer's
/// only leg), the second the left.
pub const SIDES: [&str; MAX_LEGS] = ["right", "left"];

/// Names of the two actuated joints of a leg, in index order (a two-leg URDF prefixes
/// them with the leg's side: `right_hip`).
pub const JOINT_NAMES: [&str; 2] = ["hip", "knee"];

/// One `T` per leg of a trainer of one or two legs. A one-leg value's second slot holds
/// `T::default()` and is never shown.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PerLeg<T> {
    len: usize,
    items: [T; MAX_LEGS],
}

impl<T: Copy + Default> PerLeg<T> {
    /// `f(leg)` for each of `legs` legs (1 or 2; more are cut to [`MAX_LEGS`], none is one).
    pub fn from_fn(legs: usize, mut f: impl FnMut(usize) -> T) -> Self {
        let len = legs.clamp(1, MAX_LEGS);
        let mut items = [T::default(); MAX_LEGS];
        for (i, item) in items.iter_mut().enumerate().take(len) {
            *item = f(i);
        }
        Self { len, items }
    }

    /// The same value on each of `legs` legs.
    pub fn splat(legs: usize, value: T) -> Self {
        Self::from_fn(legs, |_| value)
    }

    /// One leg's value.
    pub fn one(value: T) -> Self {
        Self::from_fn(1, |_| value)
    }

    /// Each leg's value through `f`.
    pub fn map<U: Copy + Default>(&self, mut f: impl FnMut(&T) -> U) -> PerLeg<U> {
        PerLeg::from_fn(self.len, |i| f(&self.items[i]))
    }
}

impl<T> PerLeg<T> {
    /// Number of legs.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Never: a trainer has at least one leg.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The legs' values, in leg order.
    pub fn as_slice(&self) -> &[T] {
        &self.items[..self.len]
    }

    /// The legs' values, to change them.
    pub fn as_mut_slice(&mut self) -> &mut [T] {
        &mut self.items[..self.len]
    }

    /// The legs' values, in leg order.
    pub fn iter(&self) -> std::slice::Iter<'_, T> {
        self.as_slice().iter()
    }

    /// Leg `i`'s value, if the trainer has that leg.
    pub fn get(&self, i: usize) -> Option<&T> {
        self.as_slice().get(i)
    }
}

impl<T> std::ops::Index<usize> for PerLeg<T> {
    type Output = T;
    fn index(&self, i: usize) -> &T {
        &self.as_slice()[i]
    }
}

impl<T> std::ops::IndexMut<usize> for PerLeg<T> {
    fn index_mut(&mut self, i: usize) -> &mut T {
        &mut self.as_mut_slice()[i]
    }
}

impl<'a, T> IntoIterator for &'a PerLeg<T> {
    type Item = &'a T;
    type IntoIter = std::slice::Iter<'a, T>;
    fn into_iter(self) -> Self::IntoIter {
        self.iter()
    }
}

/// A trainer's readings and commands as the supervisor sees them: leg after leg, `K`
/// channels each (a leg's two joint angles, its four pressures). A one-leg value's second
/// leg reads 0 and the supervisor's windows (one per real channel) never look at it.
impl<const K: usize> Channels for PerLeg<[f64; K]> {
    const COUNT: usize = MAX_LEGS * K;

    fn channel(&self, i: usize) -> f64 {
        self.items[i / K][i % K]
    }

    fn set_channel(&mut self, i: usize, value: f64) {
        self.items[i / K][i % K] = value;
    }

    fn zeroed() -> Self {
        Self {
            len: MAX_LEGS,
            items: [[0.0; K]; MAX_LEGS],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_leg_shows_one_value_and_two_show_two() {
        let one = PerLeg::one([1.0, 2.0]);
        assert_eq!(one.len(), 1);
        assert_eq!(one.as_slice(), &[[1.0, 2.0]]);
        let two = PerLeg::from_fn(2, |i| [i as f64; 2]);
        assert_eq!(two.iter().count(), 2);
        assert_eq!(two[1], [1.0, 1.0]);
        assert_eq!(PerLeg::from_fn(5, |i| i).len(), MAX_LEGS);
    }

    #[test]
    fn channels_run_leg_after_leg() {
        let mut two = PerLeg::from_fn(2, |i| [10.0 * i as f64, 10.0 * i as f64 + 1.0]);
        assert_eq!(
            (0..4).map(|i| two.channel(i)).collect::<Vec<_>>(),
            [0.0, 1.0, 10.0, 11.0]
        );
        two.set_channel(3, 5.0);
        assert_eq!(two[1], [10.0, 5.0]);
    }
}
