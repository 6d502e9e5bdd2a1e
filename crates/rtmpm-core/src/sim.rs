//! The backend trait and the simulation driver.
