//! What the simulated devices share: a sans-IO core (frames in, frames
//! out, timers) and the two ways of driving it, stepped on a simulated bus
//! or in real time on any bus.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use motorwire_can::{CanBus, Frame, SimPort};

use crate::SimError;

/// A simulated device's sans-IO core.
pub(crate) trait Device {
    /// What it reports of a frame it acted on.
    type Acted;
    fn handle_frame(&mut self, now: Duration, frame: &Frame) -> Option<Self::Acted>;
    fn handle_timeout(&mut self, now: Duration);
    fn poll_transmit(&mut self) -> Option<Frame>;
    fn poll_timeout(&self) -> Option<Duration>;
}

/// One pass on a simulated bus at simulated time `now`: every frame due
/// on `port`, the timers due, and what the device has to send. Whether it
/// received or sent anything.
pub(crate) fn serve<D: Device>(
    device: &mut D,
    port: &mut SimPort,
    now: Duration,
) -> Result<bool, SimError> {
    let mut busy = false;
    while let Some(r) = port.try_recv() {
        device.handle_frame(now, &r.frame);
        busy = true;
    }
    if device.poll_timeout().is_some_and(|t| t <= now) {
        device.handle_timeout(now);
    }
    while let Some(f) = device.poll_transmit() {
        port.send(&f)?;
        busy = true;
    }
    Ok(busy)
}

/// Runs `device` on `bus` in real time until `stop` is set; `on_acted`
/// sees what it acted on.
pub(crate) fn run<D: Device>(
    device: &mut D,
    bus: &mut impl CanBus,
    stop: &AtomicBool,
    mut on_acted: impl FnMut(&D::Acted),
) -> Result<(), SimError> {
    let start = Instant::now();
    let tick = Duration::from_millis(10);
    while !stop.load(Ordering::Relaxed) {
        let now = start.elapsed();
        device.handle_timeout(now);
        while let Some(f) = device.poll_transmit() {
            bus.send(&f)?;
        }
        let wait = device
            .poll_timeout()
            .map_or(tick, |t| t.saturating_sub(start.elapsed()))
            .min(tick);
        match bus.recv(wait) {
            Ok(r) => {
                if let Some(e) = device.handle_frame(start.elapsed(), &r.frame) {
                    on_acted(&e);
                }
            }
            Err(motorwire_can::Error::Timeout(_)) => {}
            Err(e) => return Err(e.into()),
        }
        while let Some(f) = device.poll_transmit() {
            bus.send(&f)?;
        }
    }
    Ok(())
}
