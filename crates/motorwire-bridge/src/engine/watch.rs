//! Arrival watches: whether a motion line's moves got where they were sent.

use super::*;

impl Bridge {
    /// Watches a motion line's acked moves until they arrive. A line that
    /// ends after a newer line moved one of its joints (a sequential line
    /// ends with its last axis), or after a stop, has its verdict at once.
    pub(super) fn watch(&mut self, meta: LineMeta, moved: Vec<WatchAxis>, since: Duration) {
        let now = self.now;
        let line = meta.at();
        let replaced_by = moved.iter().find_map(|a| {
            self.joints
                .get(a.joint)
                .and_then(|j| j.schedule.moved_by())
                .filter(|by| *by != line)
        });
        let mut w = self.watch_of(meta, moved, since);
        let origin = w.line.origin;
        let verdict = if self.stop.is_latched() {
            Some("stopped by the emergency stop".to_owned())
        } else {
            replaced_by.map(crate::output::json::superseded_by)
        };
        if let Some(why) = verdict {
            let arrival = w.verdict(now, Some(why));
            self.out.push_back(Output::Arrival { origin, arrival });
            return;
        }
        // Already there (a move to where it stands)?
        let mut done = false;
        for (ji, j) in self.joints.with_ids() {
            if let Some((pos, vel)) = j.motion.reported()
                && w.axes.iter().any(|a| a.joint == ji)
            {
                done = w.observe(ji, pos, vel, now) || done;
            }
        }
        if done && w.axes.iter().all(|a| a.arrived.is_some()) {
            let arrival = w.verdict(now, None);
            self.out.push_back(Output::Arrival { origin, arrival });
        } else {
            self.arrivals.push(w);
        }
    }

    /// Device `ji`'s part of a watch: `motor`'s move to `target`
    /// (degrees), within the map's arrival tolerance.
    pub(super) fn watch_axis(&self, ji: DeviceId, motor: String, target: f64) -> WatchAxis {
        let (unit, tolerance) = self.joints.get(ji).map_or((AngleUnit::Degrees, 0.1), |j| {
            (j.identity.unit(), j.identity.tolerance())
        });
        WatchAxis {
            joint: ji,
            motor,
            target,
            tolerance,
            unit,
            arrived: None,
            last_error: None,
        }
    }

    /// The watch of line `meta`'s moves (`axes`, [`Bridge::watch_axis`]),
    /// its result given at `since`: due by the end of the devices'
    /// planned motion and a margin.
    pub(super) fn watch_of(&self, meta: LineMeta, axes: Vec<WatchAxis>, since: Duration) -> Watch {
        let now = self.now;
        let end = axes
            .iter()
            .filter_map(|a| self.joints.get(a.joint))
            .map(|j| j.schedule.moving_until())
            .fold(now, Duration::max);
        let planned = end.saturating_sub(now);
        let margin = (planned / 4).max(Duration::from_millis(500));
        Watch {
            line: meta,
            since,
            deadline: end.saturating_add(margin),
            axes,
        }
    }

    /// Joint `ji` is at `position` moving at `velocity` (degrees): the
    /// lines that have now arrived are said so.
    pub(super) fn observe(&mut self, ji: DeviceId, position: f64, velocity: f64, at: Duration) {
        let mut i = 0;
        while let Some(w) = self.arrivals.get_mut(i) {
            if w.axes.iter().any(|a| a.joint == ji) && w.observe(ji, position, velocity, at) {
                let w = self.arrivals.remove(i);
                let origin = w.line.origin;
                let arrival = w.verdict(at, None);
                self.out.push_back(Output::Arrival { origin, arrival });
            } else {
                i += 1;
            }
        }
    }

    /// The watched lines `pick` chooses will not arrive: said, with `why`.
    pub(super) fn fail_watches(&mut self, pick: impl Fn(&Watch) -> bool, why: &str) {
        self.fail_watches_with(pick, || why.to_owned());
    }

    /// [`Self::fail_watches`] with the reason made only when a watch
    /// fails (a line's own supersession is looked for on every move).
    pub(super) fn fail_watches_with(
        &mut self,
        pick: impl Fn(&Watch) -> bool,
        why: impl Fn() -> String,
    ) {
        let now = self.now;
        let mut i = 0;
        while let Some(w) = self.arrivals.get(i) {
            if pick(w) {
                let w = self.arrivals.remove(i);
                let origin = w.line.origin;
                let arrival = w.verdict(now, Some(why()));
                self.out.push_back(Output::Arrival { origin, arrival });
            } else {
                i += 1;
            }
        }
    }

    // ---- the bus --------------------------------------------------------

    /// Device `ji` was reported at `position` moving at `velocity`
    /// (degrees) at `at`, by any driver: the lines that have now arrived
    /// are said so, and sequential axes waiting on it may go.
    pub(super) fn moved(&mut self, ji: DeviceId, position: f64, velocity: f64, at: Duration) {
        if !self.arrivals.is_empty() {
            self.observe(ji, position, velocity, at);
        }
        self.sequence_progress(ji, position, velocity);
    }

    /// The devices `pick` chooses.
    pub(super) fn joints_where(&self, pick: impl Fn(&Joint) -> bool) -> Vec<DeviceId> {
        self.joints
            .with_ids()
            .filter(|(_, j)| pick(j))
            .map(|(i, _)| i)
            .collect()
    }
}
