//! Runs that go wrong and runs under pressure: participants that die, stall or send bad data,
//! link effects, command-line values at their limits, signals, a full disk, and many runs at
//! once beside CPU hogs on a two-CPU machine. None asserts a wall-clock duration.

mod failures;
mod faults;
mod limits;
mod load;
mod placement;
mod resources;
