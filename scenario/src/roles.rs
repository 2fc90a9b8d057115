//! A value per participant role, indexed by [`Role`] instead of a number.

use std::ops::{Index, IndexMut};

use tiltsim_protocol::Role;

/// One `T` for each of [`Role::ALL`], in that order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RoleMap<T>([T; 3]);

fn slot(r: Role) -> usize {
    match r {
        Role::Plant => 0,
        Role::Actuator => 1,
        Role::Controller => 2,
    }
}

impl<T> RoleMap<T> {
    /// Values in [`Role::ALL`] order (plant, actuator, controller).
    pub fn new(values: [T; 3]) -> Self {
        RoleMap(values)
    }

    /// The values in [`Role::ALL`] order.
    pub fn into_array(self) -> [T; 3] {
        self.0
    }

    /// Each role with its value.
    pub fn iter(&self) -> impl Iterator<Item = (Role, &T)> {
        Role::ALL.into_iter().zip(self.0.iter())
    }

    /// A map of the same roles with `f` applied to each value.
    pub fn map<U>(self, f: impl FnMut(T) -> U) -> RoleMap<U> {
        RoleMap(self.0.map(f))
    }
}

impl<T> Index<Role> for RoleMap<T> {
    type Output = T;
    fn index(&self, r: Role) -> &T {
        &self.0[slot(r)]
    }
}

impl<T> IndexMut<Role> for RoleMap<T> {
    fn index_mut(&mut self, r: Role) -> &mut T {
        &mut self.0[slot(r)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_are_found_by_role() {
        let mut m = RoleMap::new([1, 2, 3]);
        m[Role::Controller] += 10;
        assert_eq!(m[Role::Plant], 1);
        assert_eq!(m[Role::Actuator], 2);
        assert_eq!(m[Role::Controller], 13);
        let names: Vec<_> = m.iter().map(|(r, v)| format!("{r}={v}")).collect();
        assert_eq!(names, ["plant=1", "actuator=2", "controller=13"]);
    }
}
