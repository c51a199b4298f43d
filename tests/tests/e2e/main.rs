//! End-to-end tests: the real `cryofit` binary as coordinator and workers on loopback ports.

mod common;
mod crossval;
mod dashboard;
mod deploy;
mod hardening;
mod input;
mod service;
