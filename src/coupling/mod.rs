//! Layer coupling: LK14 constraint kernels (the KCK18 surface walk joins here with issue 6).

pub mod kernels;
