//! qfa-lab
