//! Motion built from lines: a motor command, a multi-axis command, a trajectory, SafetyLimits; each checked against the limits in force before a job is opened.

use super::*;

impl Bridge {
    /// WIA Trajectories for iRPC joints (one, or several on one time base):
    /// each planned and checked whole ([`plan::trajectory`]) before
    /// anything is sent, then each segment sent at its time
    /// (`timing.start_time` in the future schedules the start). Each joint
    /// must stand at its first waypoint.
    pub(super) fn trajectories(
        &mut self,
        now: Duration,
        meta: LineMeta,
        id: &str,
        all: &[Trajectory],
    ) {
        // One trajectory: labelled by its motor; several: by their id.
        let meta = meta.labelled(match all {
            [one] => Label::Motor(one.motor_id.clone()),
            _ => Label::Command(id.to_owned()),
        });
        let planned = self
            .trajectory_start(now, &meta, all)
            .and_then(|start| self.builder().trajectory_axes(all, start));
        match planned {
            Ok((axes, report)) => self.command_job(now, meta, axes, report),
            Err(e) => self.refuse(&meta, e),
        }
    }

    /// When trajectories `all` of the line `meta` start: the first
    /// `start_time` given, or now; or why they are refused (the line not
    /// admitted, a start too far ahead or that no clock reaches).
    fn trajectory_start(
        &self,
        now: Duration,
        meta: &LineMeta,
        all: &[Trajectory],
    ) -> Result<Duration, Refusal> {
        let now_ms = self.unix_ms(now);
        // One time base: the first `start_time` given, or now.
        let start_ms = all
            .iter()
            .find_map(|t| t.timing.start_time)
            .unwrap_or(now_ms);
        self.admission().admit(
            now,
            Some(meta.origin),
            start_ms.min(now_ms),
            all.iter().map(|t| t.motor_id.as_str()),
        )?;
        if let (Some(_), Some(max_age)) = (self.config.epoch_unix_ms, self.config.max_age)
            && start_ms - now_ms > max_age.as_secs_f64() * 1000.0
        {
            return Err(Refusal::StartTooFarAhead {
                start_ms,
                ahead_ms: start_ms - now_ms,
                max_age,
            });
        }
        // A start_time so far ahead that no clock reaches it (1e300) is
        // refused, never a panic.
        let Ok(delay) = Duration::try_from_secs_f64(((start_ms - now_ms) / 1000.0).max(0.0)) else {
            return Err(Refusal::StartUnreachable { start_ms });
        };
        Ok(now.saturating_add(delay))
    }

    // ---- one motor held, freed or stopped ---------------------------------------

    /// A WIA SafetyLimits line: the motor's gate is held to these limits
    /// from now on (until another such line). Each limit must lie within
    /// the bus map's; a wider one refuses the whole line.
    pub(super) fn safety_limits(&mut self, meta: LineMeta, l: &SafetyLimits) {
        let name = l.motor_id.clone();
        let meta = meta.labelled(Label::Motor(name.clone()));
        let Some(base) = self.base_limits.get(&name).copied() else {
            self.refuse(&meta, Refusal::UnknownMotor { motor: name });
            return;
        };
        let wider = wider_limits(l, &base);
        if !wider.is_empty() {
            let e = Refusal::WiderThanBusMap { motor: name, wider };
            self.refuse(&meta, e);
            return;
        }
        // The soft limits, where given, are the gate's; the torque a
        // command may hold is the continuous one.
        let p = &l.position_limits;
        let lo = p.soft_min.map_or(p.min, |s| s.max(p.min));
        let hi = p.soft_max.map_or(p.max, |s| s.min(p.max));
        // Motion already accepted is held to the new limits too: a line
        // it would break is refused, naming it, and nothing changes.
        if let Some(why) = self.joint_index(&name).and_then(|ji| {
            self.builder()
                .motion_outside(ji, lo, hi, l.velocity_limits.max_velocity)
        }) {
            let e = Refusal::MotionOutsideNewLimits {
                motor: name,
                motion: why,
            };
            self.refuse(&meta, e);
            return;
        }
        self.hold_to(&name, l, base, lo, hi);
        let r = LineResult {
            ok: true,
            line: meta.number,
            limits: self.limits_value(&name),
            losses: safety_limits_losses(l),
            ..LineResult::default()
        };
        self.answer(&meta, r);
    }

    /// Motor `name`'s gate held to SafetyLimits `l` from now on (within the
    /// bus map's `base`; its positions `lo..=hi`): the map's limits, the
    /// joint's pace, its driver told, its emergency deceleration kept.
    fn hold_to(&mut self, name: &str, l: &SafetyLimits, base: Limits, lo: f64, hi: f64) {
        let v = &l.velocity_limits;
        let t = &l.torque_limits;
        let torque = match (t.continuous_torque, t.peak_torque) {
            (Some(c), Some(k)) => Some(c.min(k)),
            (c, k) => c.or(k).or(base.max_torque),
        };
        let limits = Limits {
            min_position: Some(lo),
            max_position: Some(hi),
            max_velocity: v.max_velocity.or(base.max_velocity),
            max_torque: torque,
            ..base
        };
        self.map
            .set_limits(name, limits, "the SafetyLimits line in force");
        if let Some(ji) = self.joint_index(name) {
            let motor = self.map.motor(name);
            if let (Some(j), Some(m)) = (self.joints.get_mut(ji), motor) {
                j.identity.limits_changed(m);
            }
            let unit = motor.map_or(AngleUnit::Degrees, |m| m.unit);
            self.drivers.limits_changed(ji, &InForce::of(unit, &limits));
        }
        match v.emergency_decel {
            Some(d) => self.emergency_decel.insert(name.to_owned(), d),
            None => self.emergency_decel.remove(name),
        };
    }

    pub(super) fn joint_index(&self, motor: &str) -> Option<DeviceId> {
        self.joints.find(|j| j.identity.name() == motor)
    }

    pub(super) fn motor_command(&mut self, now: Duration, meta: LineMeta, cmd: &mut MotorCommand) {
        let meta = meta.labelled(Label::Motor(cmd.motor_id.clone()));
        self.learn_clock(now, meta.origin, cmd.timestamp);
        if let Err(e) = self.admission().admit(
            now,
            Some(meta.origin),
            cmd.timestamp,
            std::iter::once(cmd.motor_id.as_str()),
        ) {
            if e.kind() == ErrorKind::Busy {
                self.stats.busy += 1;
            }
            self.refuse(&meta, e);
            return;
        }
        // Its joint, looked for once.
        let ji = self.joint_index(&cmd.motor_id);
        let device = ji.and_then(|ji| Some((ji, self.joints.get(ji)?.identity.device())));
        // A joint is attached (an Orion motor is one only with its
        // controller); anything else may be an Orion motor without one.
        if ji.is_none()
            && let Some(e) = self.unattached(std::iter::once(cmd.motor_id.as_str()))
        {
            self.refuse(&meta, e);
            return;
        }
        if cmd
            .safety_limits
            .as_ref()
            .is_none_or(|l| l.emergency_stop != Some(true))
            && let Some(e) = self.outward_at_limit(&cmd.motor_id, cmd.control_mode, cmd.setpoint)
        {
            self.refuse(&meta, e);
            return;
        }
        if let Some((ji, device)) = device
            && let Some(built) = self.builder().single_axis(ji, device, cmd)
        {
            self.device_command(now, meta, cmd, built);
            return;
        }
        match plan::gate(&self.map, cmd) {
            Ok(gated) => {
                let Some(joint) = ji else {
                    let e = Refusal::NotAnIrpcJoint {
                        motor: std::mem::take(&mut cmd.motor_id),
                    };
                    self.refuse(&meta, e);
                    return;
                };
                let from = self.joints.get(joint).and_then(|j| j.state_at(self.now));
                let planned = gated.plan_from(from);
                let (orders, report) = gated.into_parts();
                match planned {
                    Ok(planned) => self.keep_plan(joint, planned),
                    Err(r) => {
                        self.refuse(&meta, Refusal::gate(r));
                        return;
                    }
                }
                // The line's motor name, moved: the command is not read again.
                let motor = std::mem::take(&mut cmd.motor_id);
                let axes = vec![Axis::of(motor, joint, orders)];
                self.command_job(now, meta, axes, report);
            }
            Err(r) => self.refuse(&meta, Refusal::gate(r)),
        }
    }

    /// A multi-axis command: the iRPC joints' axes planned together
    /// (synchronized as the command asks), every compact device's and
    /// Orion motor's axis gated and translated on its own, all sent as one
    /// job. `sync_mode: sequential` runs them one after another, each once
    /// the one before arrived.
    pub(super) fn multi_axis_jobs(
        &mut self,
        now: Duration,
        meta: LineMeta,
        cmd: &MultiAxisCommand,
    ) {
        let meta = meta.labelled(Label::Command(cmd.command_id.clone()));
        // One after another, or together in one duration: not both (each
        // axis took the duration, one after the other, and the result
        // promised them all after it).
        if cmd.sync_mode == Some(SyncMode::Sequential)
            && cmd
                .coordination
                .as_ref()
                .is_some_and(|c| c.total_duration_ms.is_some())
        {
            return self.refuse(&meta, Refusal::SequentialWithTotalDuration);
        }
        let (mut axes, report) = match self.builder().mixed_axes(cmd) {
            Ok(x) => x,
            Err(e) => return self.refuse(&meta, e),
        };
        if cmd.sync_mode == Some(SyncMode::Sequential) {
            // One after another: each starts once the one before it
            // arrived, so each must be a move to a target.
            if let Some((a, i)) = axes
                .iter()
                .zip(&cmd.motors)
                .find(|(ax, _)| ax.target.is_none())
            {
                let e = Refusal::SequentialWithoutArrival {
                    motor: a.motor.clone(),
                    mode: i.control_mode.name(),
                };
                return self.refuse(&meta, e);
            }
            for (k, a) in axes.iter_mut().enumerate().skip(1) {
                a.after = Some(k - 1);
            }
        }
        self.command_job(now, meta, axes, report);
    }

    /// Opens the job of a command line: `axes`, `report`'s losses.
    pub(super) fn command_job(
        &mut self,
        now: Duration,
        meta: LineMeta,
        axes: Vec<Axis>,
        report: Report,
    ) {
        self.open_job(Some(meta), JobKind::Command, now, axes, report, Vec::new());
    }

    /// A MotorCommand for one compact device or Orion motor: its axis as
    /// `built`, or the refusal.
    pub(super) fn device_command(
        &mut self,
        now: Duration,
        meta: LineMeta,
        cmd: &MotorCommand,
        built: Result<(Axis, Report), motorwire_translate::Refusal>,
    ) {
        let meta = meta.labelled(Label::Motor(cmd.motor_id.clone()));
        match built {
            Ok((axis, report)) => self.command_job(now, meta, vec![axis], report),
            Err(r) => self.refuse(&meta, Refusal::gate(r)),
        }
    }

    /// Keeps the plan [`plan::Gated::plan_from`] made for `joint`'s move.
    pub(super) fn keep_plan(&mut self, joint: DeviceId, planned: Option<Plan>) {
        let now = self.now;
        if let Some(j) = self.joints.get_mut(joint) {
            let (planned, profile) = planned.unzip();
            j.motion.keep_plan(planned, profile, now);
        }
    }

    pub(super) fn multi_axis(&mut self, now: Duration, meta: LineMeta, cmd: &MultiAxisCommand) {
        let meta = meta.labelled(Label::Command(cmd.command_id.clone()));
        self.learn_clock(now, meta.origin, cmd.timestamp);
        if let Err(e) = self.admission().admit(
            now,
            Some(meta.origin),
            cmd.timestamp,
            cmd.motors.iter().map(|a| a.motor_id.as_str()),
        ) {
            if e.kind() == ErrorKind::Busy {
                self.stats.busy += 1;
            }
            self.refuse(&meta, e);
            return;
        }
        if let Some(e) = cmd
            .motors
            .iter()
            .find_map(|a| self.outward_at_limit(&a.motor_id, a.control_mode, a.setpoint))
        {
            self.refuse(&meta, e);
            return;
        }
        if let Some(e) = self.unattached(cmd.motors.iter().map(|a| a.motor_id.as_str())) {
            self.refuse(&meta, e);
            return;
        }
        self.multi_axis_jobs(now, meta, cmd);
    }

    /// Motion as the bridge stands now: what builds a line's moves.
    #[inline]
    pub(super) fn builder(&self) -> MotionBuilder<'_> {
        MotionBuilder {
            map: &self.map,
            joints: &self.joints,
            jobs: &self.jobs,
            now: self.now,
        }
    }
}

/// Building motion: a line's moves from the bus map, where each device is
/// and what is queued for it, checked against the limits before anything
/// is sent. It reads the bridge and changes nothing: the jobs it builds
/// are opened (and the plans kept) by the bridge.
pub(super) struct MotionBuilder<'a> {
    pub(super) map: &'a BusMap,
    pub(super) joints: &'a Joints,
    pub(super) jobs: &'a Jobs,
    /// The bridge's clock.
    pub(super) now: Duration,
}

impl MotionBuilder<'_> {
    /// The device named `motor` in the bus map.
    pub(super) fn joint_index(&self, motor: &str) -> Option<DeviceId> {
        self.joints.find(|j| j.identity.name() == motor)
    }

    /// An axis for each of trajectories `all`, starting at `start`, and
    /// what their planning lost; or why the line is refused (a motor
    /// twice, or the first refusal of a trajectory).
    pub(super) fn trajectory_axes(
        &self,
        all: &[Trajectory],
        start: Duration,
    ) -> Result<(Vec<Axis>, Report), Refusal> {
        let mut axes = Vec::new();
        let mut report = Report::default();
        let mut seen = std::collections::BTreeSet::new();
        for t in all {
            if !seen.insert(t.motor_id.as_str()) {
                return Err(Refusal::MotorTwice {
                    motor: t.motor_id.clone(),
                });
            }
            axes.push(self.trajectory_axis(t, all.len() > 1, start, &mut report)?);
        }
        Ok((axes, report))
    }

    /// Trajectory `t` planned for its joint, starting at `start`: its axis,
    /// what its planning lost added to `report` (under its motor when the
    /// line has `several`); or why it is refused (its plan's refusal, not a
    /// joint that takes trajectories, the joint not at its first waypoint,
    /// a time no clock reaches).
    fn trajectory_axis(
        &self,
        t: &Trajectory,
        several: bool,
        start: Duration,
        report: &mut Report,
    ) -> Result<Axis, Refusal> {
        let plan = plan::trajectory(self.map, t).map_err(Refusal::gate)?;
        let Some(ji) = self.joint_index(&t.motor_id).filter(|&ji| {
            self.joints
                .get(ji)
                .is_some_and(|j| j.identity.device().supports(Capability::Trajectory))
        }) else {
            return Err(Refusal::NotAnIrpcJoint {
                motor: t.motor_id.clone(),
            });
        };
        self.check_at_start(ji, t)?;
        for loss in plan.report.losses {
            report.losses.push(if several {
                loss.under(&t.motor_id)
            } else {
                loss
            });
        }
        // Times no clock reaches are refused, never a panic.
        let timeable = |secs: f64| Duration::try_from_secs_f64(secs.max(0.0)).is_ok();
        if !plan.value.segments.iter().all(|s| timeable(s.0)) || !timeable(plan.value.duration) {
            return Err(Refusal::WaypointUnreachable {
                motor: t.motor_id.clone(),
            });
        }
        Ok(self.segment_axis(t, ji, &plan.value, start))
    }

    /// Whether joint `ji` stands at trajectory `t`'s first waypoint
    /// (within its arrival tolerance).
    fn check_at_start(&self, ji: DeviceId, t: &Trajectory) -> Result<(), Refusal> {
        let (unit, tolerance) = self
            .map
            .motor(&t.motor_id)
            .map_or((AngleUnit::Degrees, 0.1), |m| {
                (m.unit, m.unit.to_degrees(m.arrival_tolerance))
            });
        let first = t
            .waypoints
            .first()
            .map_or(0.0, |w| unit.to_degrees(w.position));
        let here = self
            .joints
            .get(ji)
            .and_then(|j| j.motion.reported())
            .map(|(p, _)| p);
        if here.is_none_or(|p| !p.is_finite() || (p - first).abs() > tolerance) {
            return Err(Refusal::NotAtStart {
                motor: t.motor_id.clone(),
                first: short_unit(unit.from_degrees(first)),
                at: here.map(|p| short_unit(unit.from_degrees(p))),
            });
        }
        Ok(())
    }

    /// The axis of joint `ji` that runs `plan` (trajectory `t`'s) from
    /// `start`: each segment as the device takes it (an iRPC joint its
    /// SetTargetV2; a moteus controller a position-mode move within the
    /// segment's limits, its torque limit the map's in force), each at its
    /// time, cycled when it loops forever.
    fn segment_axis(
        &self,
        t: &Trajectory,
        ji: DeviceId,
        plan: &plan::TrajectoryPlan,
        start: Duration,
    ) -> Axis {
        let device = self.joints.get(ji).map(|j| j.identity.device());
        let max_torque = self
            .map
            .motor(&t.motor_id)
            .and_then(|m| m.limits.max_torque);
        let orders: Vec<Order> = plan
            .segments
            .iter()
            .filter_map(|s| device.and_then(|d| d.segment_order(s.1, max_torque)))
            .collect();
        let mut axis = Axis::of(t.motor_id.clone(), ji, orders.iter().copied());
        axis.due = plan
            .segments
            .iter()
            .map(|s| start.saturating_add(Duration::from_secs_f64(s.0.max(0.0))))
            .collect();
        if plan.forever {
            axis.cycle = Some(Cycle {
                payloads: plan
                    .segments
                    .iter()
                    .zip(orders)
                    .map(|(s, o)| (Duration::from_secs_f64(s.0.max(0.0)), o))
                    .collect(),
                period: Duration::from_secs_f64(plan.duration),
                started: start,
            });
        }
        axis
    }

    /// The first motion of device `ji` already accepted (its move under
    /// way, what is in flight, what waits to be sent, a trajectory's later
    /// segments and cycles) that positions `lo..=hi` or a `max_v` (the
    /// motor's unit) would not allow: what it is, said for a person.
    pub(super) fn motion_outside(
        &self,
        ji: DeviceId,
        lo: f64,
        hi: f64,
        max_v: Option<f64>,
    ) -> Option<String> {
        let j = self.joints.get(ji)?;
        let unit = self
            .map
            .motor(j.identity.name())
            .map_or(AngleUnit::Degrees, |m| m.unit);
        let w = Within {
            lo: unit.to_degrees(lo),
            hi: unit.to_degrees(hi),
            max_v: max_v.map(|v| unit.to_degrees(v)),
            unit,
        };
        if j.schedule.is_moving(self.now) {
            if let Some(t) = j.schedule.target().filter(|t| w.outside(*t)) {
                return Some(format!("its move under way goes to {}", w.say(t)));
            }
            if let Some((_, v)) = j.motion.reported().filter(|(_, v)| w.faster(*v)) {
                return Some(format!("it moves at {} a second now", w.say(v.abs())));
            }
        }
        self.rest_of_move_outside(j, &w)
            .or_else(|| self.steps_outside(j, &w))
    }

    /// Where the rest of joint `j`'s move under way goes farther out than
    /// `w` (a move braking from speed toward a target inside passes it):
    /// as the bridge planned it, or without that plan, at least the stop
    /// from where the joint is at its limits. A joint already past a new
    /// limit is held to going no farther (as one standing there is: the
    /// limits bind what comes next); going farther out is refused.
    fn rest_of_move_outside(&self, j: &Joint, w: &Within) -> Option<String> {
        let (p_now, v_now, _) = j.state_at(self.now)?;
        let farther = |x: f64| {
            (x > w.hi + SLACK && x > p_now + SLACK) || (x < w.lo - SLACK && x < p_now - SLACK)
        };
        let rest = match j.motion.model() {
            Some((start, profile)) => {
                let t = self.now.saturating_sub(*start).as_secs_f64();
                (t < profile.duration()).then(|| {
                    let e = profile.position_extrema_from(t);
                    [(e.max, e.t_max - t), (e.min, e.t_min - t)]
                })
            }
            None if v_now != 0.0 => self.stop_extrema(j, w.unit, p_now, v_now),
            None => None,
        };
        for (extreme, after) in rest.into_iter().flatten() {
            if farther(extreme) {
                return Some(format!(
                    "its move under way reaches {} in {:.3} s",
                    w.say(extreme),
                    after.max(0.0)
                ));
            }
        }
        None
    }

    /// The extremes of joint `j`'s stop from `p_now` at `v_now` (degrees)
    /// at its bus map limits, and how long after now each is reached.
    fn stop_extrema(
        &self,
        j: &Joint,
        unit: AngleUnit,
        p_now: f64,
        v_now: f64,
    ) -> Option<[(f64, f64); 2]> {
        let l = self.map.motor(j.identity.name())?.limits;
        let deg = |x: Option<f64>| x.map(|v| unit.to_degrees(v));
        let acc = deg(l.max_acceleration).unwrap_or(1000.0);
        let mut req = motorwire_planner::Request::new(
            p_now,
            p_now,
            deg(l.max_velocity).unwrap_or(v_now.abs()).max(v_now.abs()),
            acc,
        )
        .with_velocities(v_now, 0.0)
        .with_max_deceleration(deg(l.max_deceleration).unwrap_or(acc));
        if let Some(jerk) = deg(l.max_jerk).filter(|j| *j > 0.0) {
            req = req.with_jerk(jerk);
        }
        let e = motorwire_planner::plan(&req).ok()?.position_extrema();
        Some([(e.max, e.t_max), (e.min, e.t_min)])
    }

    /// The first step of joint `j` in flight or waiting (a trajectory's
    /// later segments and cycles with it) that goes outside `w`.
    fn steps_outside(&self, j: &Joint, w: &Within) -> Option<String> {
        for step in j.schedule.steps() {
            let Some(job) = self.jobs.get(&step.job) else {
                continue;
            };
            let Some(a) = job.axes.get(step.axis) else {
                continue;
            };
            let in_flight = match &a.state {
                AxisState::InFlight { payload, .. } => Some(*payload),
                _ => None,
            };
            let cycle = a
                .cycle
                .iter()
                .flat_map(|c| c.payloads.iter().map(|(_, p)| *p));
            for order in in_flight
                .into_iter()
                .chain(a.payloads.iter().copied())
                .chain(cycle)
            {
                let reach = order.reach(w.unit);
                let line = job.number();
                if let Some(t) = reach.target.filter(|t| w.outside(*t)) {
                    return Some(format!("line {line} moves it to {}", w.say(t)));
                }
                if let Some(v) = reach.speed.filter(|v| w.faster(*v)) {
                    return Some(format!(
                        "line {line} moves it at {} a second",
                        w.say(v.abs())
                    ));
                }
            }
        }
        None
    }

    /// `cmd` for device `ji`, gated and translated on its own, as its
    /// axis; `None` for an iRPC joint, whose moves are planned from its
    /// state (and with the other joints of a multi-axis line).
    pub(super) fn single_axis(
        &self,
        ji: DeviceId,
        device: Device,
        cmd: &MotorCommand,
    ) -> Option<Result<(Axis, Report), motorwire_translate::Refusal>> {
        let built = device.single_order(self.map, cmd)?;
        Some(built.map(|one| {
            let mut axis = Axis::of(cmd.motor_id.clone(), ji, [one.order]);
            axis.target = one.target;
            (axis, one.report)
        }))
    }

    pub(super) fn mixed_axes(
        &self,
        cmd: &MultiAxisCommand,
    ) -> Result<(Vec<Axis>, Report), Refusal> {
        let refused = |motor: &str, r: motorwire_translate::Refusal| Refusal::Gate {
            refusal: Box::new(r),
            motor: Some(motor.to_owned()),
        };
        let mut report = Report::default();
        // The iRPC joints' axes, planned together.
        let mut sub = cmd.clone();
        sub.motors.retain(|a| {
            self.joint_index(&a.motor_id).is_some_and(|ji| {
                self.joints
                    .get(ji)
                    .is_some_and(|j| j.identity.device().planned_together())
            })
        });
        let mut together: Vec<Vec<Order>> = Vec::new();
        if !sub.motors.is_empty() {
            // Each joint from where it is now, moving or not.
            let state = |m: &str| {
                let j = self.joints.get(self.joint_index(m)?)?;
                match j.state_at(self.now) {
                    Some(k) => Some(crate::joints::in_unit(j.identity.unit(), k)),
                    None => j.motion.feedback().map(|f| (f.position, 0.0, 0.0)),
                }
            };
            let t = plan::together(self.map, &sub, &state).map_err(Refusal::gate)?;
            together = t.value;
            report.losses.extend(t.report.losses);
        }
        let mut together = together.into_iter();
        let mut axes = Vec::new();
        // The dialects of the axes not planned together, in the map's words.
        let mut others: Vec<&'static str> = Vec::new();
        for a in &cmd.motors {
            let Some(ji) = self.joint_index(&a.motor_id) else {
                return Err(Refusal::UnknownMotor {
                    motor: a.motor_id.clone(),
                });
            };
            let single = a.to_motor_command(cmd.timestamp);
            let prefixed = |r: Report| r.losses.into_iter().map(|l| l.under(&a.motor_id));
            let device = self.joints.get(ji).map(|j| j.identity.device());
            if let Some(built) = device.and_then(|d| self.single_axis(ji, d, &single)) {
                let (axis, r) = built.map_err(|r| refused(&a.motor_id, r))?;
                report.losses.extend(prefixed(r));
                axes.push(axis);
                let dialect = device.map_or("iRPC", Device::dialect_name);
                if !others.contains(&dialect) {
                    others.push(dialect);
                }
            } else {
                let orders = together.next().unwrap_or_default();
                axes.push(Axis::of(a.motor_id.clone(), ji, orders));
            }
        }
        if !others.is_empty()
            && !sub.motors.is_empty()
            && cmd.sync_mode != Some(SyncMode::Sequential)
        {
            others.sort_by_key(|d| d.to_ascii_lowercase());
            let names = match others.as_slice() {
                [one] => (*one).to_owned(),
                [init @ .., last] => format!("{} and {last}", init.join(", ")),
                [] => String::new(),
            };
            report.losses.push(motorwire_translate::Loss {
                field: "sync_mode".into(),
                kind: motorwire_translate::LossKind::Converted,
                detail: format!(
                    "{names} axes are sent at the same time as the others, but only iRPC joints are planned to a common duration"
                )
                .into(),
            });
        }
        Ok((axes, report))
    }
}

/// How far a motion checked against new limits may go (degrees, beyond
/// a slack for rounding), and the motor's unit to say it in.
struct Within {
    lo: f64,
    hi: f64,
    max_v: Option<f64>,
    unit: AngleUnit,
}

/// The rounding a motion is allowed past a limit (degrees).
const SLACK: f64 = 1e-6;

impl Within {
    /// Whether position `t` is outside.
    fn outside(&self, t: f64) -> bool {
        t < self.lo - SLACK || t > self.hi + SLACK
    }

    /// Whether velocity `v` is faster than allowed.
    fn faster(&self, v: f64) -> bool {
        self.max_v.is_some_and(|m| v.abs() > m + SLACK)
    }

    /// `d` (degrees) in the motor's unit, as said.
    fn say(&self, d: f64) -> f64 {
        short_unit(self.unit.from_degrees(d))
    }
}

/// Each limit of SafetyLimits `l` wider than the bus map's, `base`.
fn wider_limits(l: &SafetyLimits, base: &Limits) -> Vec<Wider> {
    let p = &l.position_limits;
    let v = &l.velocity_limits;
    let t = &l.torque_limits;
    let mut wider = Vec::new();
    let mut low =
        |field: &'static str, value: Option<f64>, map: Option<f64>, map_field: &'static str| {
            if let (Some(x), Some(b)) = (value, map)
                && x < b
            {
                wider.push(Wider {
                    field,
                    value: x,
                    map_field,
                    bound: b,
                });
            }
        };
    low(
        "position_limits.min",
        Some(p.min),
        base.min_position,
        "min_position",
    );
    low(
        "position_limits.soft_min",
        p.soft_min,
        base.min_position,
        "min_position",
    );
    let mut high =
        |field: &'static str, value: Option<f64>, map: Option<f64>, map_field: &'static str| {
            if let (Some(x), Some(b)) = (value, map)
                && x > b
            {
                wider.push(Wider {
                    field,
                    value: x,
                    map_field,
                    bound: b,
                });
            }
        };
    high(
        "position_limits.max",
        Some(p.max),
        base.max_position,
        "max_position",
    );
    high(
        "position_limits.soft_max",
        p.soft_max,
        base.max_position,
        "max_position",
    );
    high(
        "velocity_limits.max_velocity",
        v.max_velocity,
        base.max_velocity,
        "max_velocity",
    );
    high(
        "torque_limits.continuous_torque",
        t.continuous_torque,
        base.max_torque,
        "max_torque",
    );
    high(
        "torque_limits.peak_torque",
        t.peak_torque,
        base.max_torque,
        "max_torque",
    );
    wider
}

/// What of SafetyLimits `l` a joint does not take: an emergency
/// deceleration is only recorded, and the settings iRPC has not are
/// dropped.
fn safety_limits_losses(l: &SafetyLimits) -> Vec<motorwire_translate::Loss> {
    let mut losses = Vec::new();
    if l.velocity_limits.emergency_decel.is_some() {
        losses.push(motorwire_translate::Loss {
            field: "velocity_limits.emergency_decel".into(),
            kind: LossKind::Dropped,
            detail: "recorded; an iRPC joint brakes from a Deactivate at its own rate".into(),
        });
    }
    for (field, given) in [
        ("thermal_limits", l.thermal_limits.is_some()),
        ("current_limits", l.current_limits.is_some()),
        ("collision_detection", l.collision_detection.is_some()),
        (
            "torque_limits.peak_duration_ms",
            l.torque_limits.peak_duration_ms.is_some(),
        ),
    ] {
        if given {
            losses.push(motorwire_translate::Loss {
                field: field.into(),
                kind: LossKind::Dropped,
                detail: "iRPC has no such setting; the joint keeps its own".into(),
            });
        }
    }
    losses
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    const MAP: &str = "[motors.elbow]\ndialect = \"irpc\"\nnode = 0x12\n\
                       limits = { min_position = -90, max_position = 150, max_velocity = 120, max_acceleration = 500 }\n";

    /// A bridge on [`MAP`], running, its joint not activated.
    fn bridge() -> Bridge {
        let config = BridgeConfig {
            activate_on_start: false,
            ..BridgeConfig::default()
        };
        let mut b = Bridge::new(BusMap::from_toml(MAP).unwrap(), config).unwrap();
        b.start(Duration::ZERO);
        b
    }

    fn trajectory(motor: &str, first: f64) -> Trajectory {
        serde_json::from_str(&format!(
            r#"{{"trajectory_id":"t","motor_id":"{motor}","waypoints":[{{"position":{first},"velocity":0,"time":0}},{{"position":20,"velocity":0,"time":1}}],"timing":{{}}}}"#
        ))
        .unwrap()
    }

    /// A trajectory is built only for a joint that stands at its first
    /// waypoint: unknown before any report, refused away from it, and
    /// from there one axis whose first segment is due at the start given.
    /// A motor twice in one line is refused before anything is built.
    #[test]
    fn a_trajectory_starts_only_where_its_joint_stands() {
        let mut b = bridge();
        let start = Duration::from_millis(40);
        let one = [trajectory("elbow", 0.0)];
        assert_eq!(
            b.builder().trajectory_axes(&one, start).map(|_| ()),
            Err(Refusal::NotAtStart {
                motor: "elbow".to_owned(),
                first: 0.0,
                at: None
            })
        );
        let elbow = b.builder().joint_index("elbow").unwrap();
        b.reading(elbow, Duration::from_millis(1), Some((5.0, 0.0)), None);
        assert_eq!(
            b.builder().trajectory_axes(&one, start).map(|_| ()),
            Err(Refusal::NotAtStart {
                motor: "elbow".to_owned(),
                first: 0.0,
                at: Some(5.0)
            })
        );
        b.reading(elbow, Duration::from_millis(2), Some((0.0, 0.0)), None);
        let (axes, _) = b.builder().trajectory_axes(&one, start).unwrap();
        assert_eq!(axes.len(), 1);
        assert_eq!((axes[0].joint, axes[0].due.front()), (elbow, Some(&start)));
        let twice = [trajectory("elbow", 0.0), trajectory("elbow", 0.0)];
        assert_eq!(
            b.builder().trajectory_axes(&twice, start).map(|_| ()),
            Err(Refusal::MotorTwice {
                motor: "elbow".to_owned()
            })
        );
    }

    /// New limits are held against what a joint already does: standing at
    /// 100°, limits that keep it nowhere past 50° find nothing under way
    /// to refuse; a move line 1 sent to 140° (not yet acknowledged) is
    /// named by its line, in the motor's unit, by limits it would pass.
    #[test]
    fn new_limits_are_held_against_the_move_under_way() {
        let mut b = bridge();
        let elbow = b.builder().joint_index("elbow").unwrap();
        b.reading(elbow, Duration::from_millis(1), Some((100.0, 0.0)), None);
        assert_eq!(b.builder().motion_outside(elbow, -10.0, 50.0, None), None);
        b.handle_line(
            Duration::from_millis(2),
            Origin(1),
            r#"{"motor_id":"elbow","timestamp":0,"control_mode":"position","setpoint":140}"#,
        );
        assert_eq!(
            b.builder().motion_outside(elbow, -10.0, 120.0, None),
            Some("line 1 moves it to 140".to_owned())
        );
        assert_eq!(b.builder().motion_outside(elbow, -10.0, 145.0, None), None);
    }
}
