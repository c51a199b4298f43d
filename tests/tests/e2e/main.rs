//! End-to-end tests: the real `cryofit` binary as coordinator and workers on loopback ports.

mod common;
mod dashboard;
mod deploy;
mod input;
mod service;
