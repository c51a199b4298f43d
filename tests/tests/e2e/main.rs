//! End-to-end tests: the real `cryofit` binary as coordinator and workers on loopback ports.

mod common;
mod deploy;
mod dashboard;
mod input;
mod service;
