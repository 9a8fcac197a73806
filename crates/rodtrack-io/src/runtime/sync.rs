//! Lock and channel helpers of the pipeline's threads: a lock that survives a panicked holder,
//! and short spins before blocking (see [`super::PipelineConfig::spin`]).

use crossbeam_channel::{Receiver, RecvTimeoutError, TryRecvError};
use std::sync::{Mutex, MutexGuard, TryLockError};
use std::time::{Duration, Instant};

/// Locks `m`, also when a panicked holder poisoned it.
pub(super) fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    // A stage that panicked while holding the lock left consistent-enough state: the set it
    // was emitting is lost (its camera reports the panic), the others go on.
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// [`lock`], polling the lock for up to `spin` before blocking on it (see
/// [`super::PipelineConfig::spin`]).
pub(super) fn lock_spin<T>(m: &Mutex<T>, spin: Duration) -> MutexGuard<'_, T> {
    if !spin.is_zero() {
        let start = Instant::now();
        loop {
            match m.try_lock() {
                Ok(g) => return g,
                Err(TryLockError::Poisoned(e)) => return e.into_inner(),
                Err(TryLockError::WouldBlock) if start.elapsed() < spin => std::hint::spin_loop(),
                Err(TryLockError::WouldBlock) => break,
            }
        }
    }
    lock(m)
}

/// Polls `rx` for up to `spin`; `Err(Empty)` when nothing came in that time.
fn spin_recv<T>(rx: &Receiver<T>, spin: Duration) -> Result<T, TryRecvError> {
    let start = Instant::now();
    loop {
        match rx.try_recv() {
            Err(TryRecvError::Empty) if start.elapsed() < spin => std::hint::spin_loop(),
            r => return r,
        }
    }
}

/// Receives with a short spin first (see [`super::PipelineConfig::spin`]).
pub(super) fn recv_spin<T>(rx: &Receiver<T>, spin: Duration) -> Option<T> {
    if !spin.is_zero() {
        match spin_recv(rx, spin) {
            Ok(v) => return Some(v),
            Err(TryRecvError::Disconnected) => return None,
            Err(TryRecvError::Empty) => {}
        }
    }
    rx.recv().ok()
}

/// Receives with a short spin first, then waits up to `timeout`.
pub(super) fn recv_spin_timeout<T>(
    rx: &Receiver<T>,
    spin: Duration,
    timeout: Duration,
) -> Result<T, RecvTimeoutError> {
    if !spin.is_zero() {
        match spin_recv(rx, spin) {
            Ok(v) => return Ok(v),
            Err(TryRecvError::Disconnected) => return Err(RecvTimeoutError::Disconnected),
            Err(TryRecvError::Empty) => {}
        }
    }
    rx.recv_timeout(timeout)
}
