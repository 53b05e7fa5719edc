//! The drivers, one per dialect, behind one face: what the engine asks of the device layer (send, poll, a frame or a line in, the time) and what it is told back (`Happened`).

use super::*;

/// What the servo driver is made with: the map's serial ports, and how
/// often each is read.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ServoSetup<'a> {
    /// The bus map: its servo ports, and each servo's model and
    /// calibration.
    pub(crate) map: &'a BusMap,
    pub(crate) period: Duration,
}

/// The drivers, one per dialect: a closed set, each operation one match.
/// Every driver's news reaches the engine as [`Happened`], through
/// [`Drivers::poll`].
#[derive(Debug)]
pub(crate) struct Drivers {
    pub(super) irpc: irpc::IrpcDriver,
    pub(super) compact: compact::CompactDriver,
    pub(super) orion: orion::OrionDriver,
    pub(super) moteus: moteus::MoteusDriver,
    pub(super) servo: servo::ServoDriver,
    pub(super) queued: VecDeque<Queued>,
    /// The Unix ms of the bridge's zero (feedback timestamps).
    pub(super) epoch: f64,
    /// Whose each frame is.
    pub(super) router: Router,
    /// The devices by CAN id or node id (the first of each, in the
    /// engine's order): whose an iRPC message is.
    pub(super) by_node: HashMap<u16, DeviceId>,
}

impl Drivers {
    /// The drivers for `devices` (the engine's, in its order): the iRPC
    /// client as `client` says, each joint in its own wire version; every
    /// driver's requests wait `client.timeout` and are sent again up to
    /// `client.retries` times (an Orion command waits `arm_command_timeout`).
    ///
    /// # Errors
    /// The iRPC client's refusal of `client` (a node id beyond 11 bits).
    /// The Unix ms of the bridge's time zero, set again where the clock
    /// starts ([`crate::Bridge::anchor_epoch`]).
    pub(crate) fn set_epoch(&mut self, epoch: f64) {
        self.epoch = epoch;
    }

    pub(crate) fn new(
        client: ClientConfig,
        arm_command_timeout: Duration,
        epoch: f64,
        devices: &dyn Registry,
        servos: ServoSetup<'_>,
    ) -> Result<Self, motorwire_can::Error> {
        let mut irpc = irpc::IrpcDriver::new(client)?;
        let mut moteus = moteus::MoteusDriver::new(client.timeout, client.retries);
        for j in devices.iter() {
            match j.device {
                Device::Irpc { wire } => irpc.set_wire(j.node, wire),
                Device::Moteus {
                    id, bus, period_ms, ..
                } => moteus.poll_every(j.id, id, bus, Duration::from_millis(u64::from(period_ms))),
                Device::Compact { .. } | Device::Orion(_) | Device::Servo(_) => {}
            }
        }
        let servo = servo::ServoDriver::new(
            servos.map.servo_ports(),
            devices
                .iter()
                .filter_map(|j| match servos.map.motor(j.name)?.target {
                    Target::Servo(t) => Some((j.id, t)),
                    _ => None,
                }),
            servos.period,
            client.retries,
        );
        let mut by_node = HashMap::new();
        for j in devices.iter() {
            by_node.entry(j.node).or_insert(j.id);
        }
        Ok(Self {
            irpc,
            compact: compact::CompactDriver::new(client.timeout, client.retries),
            orion: orion::OrionDriver::new(client.timeout, client.retries, arm_command_timeout),
            moteus,
            servo,
            queued: VecDeque::new(),
            epoch,
            router: Router::new(devices.iter().map(|j| (j.id, j.node, j.device))),
            by_node,
        })
    }

    /// Sends `order` for device `device` on CAN id `node` and awaits its
    /// answer; returns the driver's number for it. An order sent together
    /// with others ([`Order::sent_together`]) goes through
    /// [`Drivers::send_together`].
    ///
    /// # Errors
    /// Why it could not be sent, said for a person; nothing was queued.
    pub(crate) fn send(
        &mut self,
        now: Duration,
        device: DeviceId,
        node: u16,
        order: Order,
    ) -> Result<u32, DeviceError> {
        match order {
            Order::Irpc(p) => self.irpc.send(now, device, node, p),
            Order::Compact(c) => {
                compact::command_frame(node, c).map(|f| self.compact.send(now, device, f))
            }
            Order::Orion(o) => self.send_together(now, &[(device, Order::Orion(o))]),
            Order::Moteus(c) => self.moteus.send(now, device, &c),
            Order::Servo(c) => Ok(self.servo.send(now, device, c)),
        }
    }

    /// Whether `order` cannot be sent now, and why (an Orion value or
    /// command before the controller's beacon).
    pub(crate) fn refuses(&self, order: &Order) -> Option<DeviceError> {
        match order {
            Order::Orion(o) => self.orion.refuses(*o),
            Order::Irpc(_) | Order::Compact(_) | Order::Moteus(_) | Order::Servo(_) => None,
        }
    }

    /// Sends `orders` (each device's, all of one line and joining the
    /// first: [`Order::joins`]) in one message; returns its number.
    ///
    /// # Errors
    /// Why it could not be sent; nothing was queued.
    pub(crate) fn send_together(
        &mut self,
        now: Duration,
        orders: &[(DeviceId, Order)],
    ) -> Result<u32, DeviceError> {
        if let Some(e) = orders.first().and_then(|(_, o)| self.refuses(o)) {
            return Err(e);
        }
        let orion: Vec<(DeviceId, OrionOrder)> = orders
            .iter()
            .filter_map(|(d, o)| match o {
                Order::Orion(o) => Some((*d, *o)),
                Order::Irpc(_) | Order::Compact(_) | Order::Moteus(_) | Order::Servo(_) => None,
            })
            .collect();
        if orion.len() != orders.len() || orion.is_empty() {
            return Err(DeviceError::NotTogether);
        }
        Ok(self.orion.send(now, &orion))
    }

    /// Whether the link `order` goes over is free for it now (the Orion
    /// controller takes one line at a time; a lost link takes the stop
    /// that is all it is written). `None`: a step with nothing to send.
    pub(crate) const fn link_free(&self, order: Option<&Order>) -> bool {
        match order {
            Some(Order::Orion(_)) => self.orion.lost() || self.orion.free(),
            Some(Order::Irpc(_) | Order::Compact(_) | Order::Moteus(_) | Order::Servo(_))
            | None => true,
        }
    }

    /// The limits in force on device `device` changed (a SafetyLimits
    /// line taken): what a driver sends from now on, and what it sends
    /// again by itself (a moteus controller's held move), follows them.
    pub(crate) fn limits_changed(&mut self, device: DeviceId, limits: &InForce) {
        self.moteus.limits_changed(device, limits);
    }

    /// Device `device`'s request in flight (`msg_id`, `order`) is given
    /// up: its answer, if it comes, is no longer awaited, and it is never
    /// sent again.
    pub(crate) fn forget(&mut self, device: DeviceId, msg_id: u32, order: Order) {
        match order {
            Order::Irpc(_) => self.irpc.forget(msg_id),
            Order::Compact(_) => self.compact.forget(device),
            Order::Orion(_) => self.orion.forget(device),
            Order::Moteus(_) => self.moteus.forget(device),
            Order::Servo(_) => self.servo.forget(device),
        }
    }

    /// Takes back what `picked` devices had made and not yet handed out
    /// (a compact frame, an Orion line all of whose devices are picked):
    /// the devices whose request was taken back, and so never sent. An
    /// iRPC request is handed to the client, which puts it on the bus at
    /// once: never taken back.
    pub(crate) fn take_back_unsent(&mut self, picked: &BTreeSet<DeviceId>) -> BTreeSet<DeviceId> {
        let mut unsent: BTreeSet<DeviceId> = picked
            .iter()
            .copied()
            .filter(|&d| {
                self.compact.take_back_unsent(d)
                    || self.moteus.take_back_unsent(d)
                    || self.servo.take_back_unsent(d)
            })
            .collect();
        if let Some(devices) = self.orion.take_back_unsent(|d| picked.contains(&d)) {
            unsent.extend(devices);
        }
        unsent
    }

    /// The next frame to put on the bus.
    pub(crate) fn poll_transmit(&mut self) -> Option<Frame> {
        self.irpc
            .poll_transmit()
            .or_else(|| self.compact.poll_transmit())
            .or_else(|| self.moteus.poll_transmit())
    }

    /// The next line for the Orion controller (without its newline).
    pub(crate) fn poll_line(&mut self) -> Option<String> {
        self.orion.poll_line()
    }

    /// The heartbeat to the bus's joints (iRPC's ArmReady). Whether it was
    /// queued (never on a bus without iRPC joints).
    pub(crate) fn heartbeat(&mut self) -> bool {
        self.irpc.heartbeat()
    }

    /// Whether any device hears the arm's heartbeat (iRPC joints).
    pub(crate) fn beats(&self) -> bool {
        self.irpc.beats()
    }

    /// Why `device` is offline, where its driver's link says so (the
    /// Orion controller before its beacon, lost, or being stopped after
    /// it came back).
    pub(crate) fn offline_reason(&self, device: Device) -> Option<&'static str> {
        match device {
            Device::Irpc { .. }
            | Device::Compact { .. }
            | Device::Moteus { .. }
            | Device::Servo(_) => None,
            Device::Orion(_) => self.orion.offline_reason(),
        }
    }

    /// The next resend or time-out of an iRPC request
    /// ([`Drivers::handle_timeout`]'s work).
    pub(crate) fn requests_deadline(&self) -> Option<Duration> {
        self.irpc.deadline()
    }

    /// The next resend or time-out of a compact or moteus command
    /// ([`Drivers::command_timeouts`]' work).
    pub(crate) fn commands_deadline(&self) -> Option<Duration> {
        [self.compact.deadline(), self.moteus.requests_deadline()]
            .into_iter()
            .flatten()
            .min()
    }

    /// The links' next work: the Orion line in flight, its recovery or
    /// poll, a moteus controller's poll ([`Drivers::link_timeouts`] and
    /// [`Drivers::link_housekeeping`]).
    pub(crate) fn link_deadline(&self) -> Option<Duration> {
        [
            self.orion.deadline(),
            self.moteus.polls_deadline(),
            self.servo.deadline(),
        ]
        .into_iter()
        .flatten()
        .min()
    }

    /// A frame from the bus at `now`, for whichever of `devices` it is.
    pub(crate) fn handle_frame(&mut self, now: Duration, frame: &Frame, devices: &dyn Registry) {
        match self.router.route(frame) {
            Route::CompactFeedback(ji) => {
                let Some(j) = devices.get(ji) else { return };
                let Device::Compact { hash, .. } = j.device else {
                    return;
                };
                match compact::feedback_record(frame, j.name, hash) {
                    Err(error) => self.tell(Happened::Bad {
                        report: Some(Event::BadFrame {
                            can_id: frame.id().to_string(),
                            error: error.to_string(),
                        }),
                    }),
                    Ok(record) => {
                        self.tell(Happened::Heard {
                            device: ji,
                            at: now,
                            up: true,
                        });
                        let motion = (
                            j.unit.to_degrees(f64::from(record.position)),
                            j.unit.to_degrees(f64::from(record.velocity)),
                        );
                        let ts = unix_ms(self.epoch, now);
                        let feedback = compact::feedback_to_wia(j.name, ts, &record);
                        self.tell(Happened::Reading {
                            device: ji,
                            at: now,
                            motion: Some(motion),
                            feedback: Some(Box::new(feedback)),
                        });
                        self.queued.push_back(Queued::CompactAck {
                            device: ji,
                            at: now,
                            stopped: !record
                                .status
                                .contains(motorwire_compact::StatusFlag::Enabled),
                        });
                    }
                }
            }
            Route::MoteusReply(ji) => self.moteus_reply(now, frame, ji, devices),
            // A compact or moteus command (ours, heard back on a second
            // socket): nothing to act on.
            Route::CompactCommand | Route::MoteusCommand => {}
            Route::Irpc => self.irpc.handle_frame(now, frame),
        }
    }

    /// Resends and time-outs of the iRPC client's requests due at `now`.
    pub(crate) fn handle_timeout(&mut self, now: Duration) {
        self.irpc.handle_timeout(now);
    }

    /// Whether `order`, in flight as request `msg_id`, is due to be sent
    /// again at `now` by its driver's retries (the iRPC client's: the
    /// orders whose path the engine holds to the limits when they go).
    pub(crate) fn resend_due(&self, msg_id: u32, order: &Order, now: Duration) -> bool {
        match order {
            Order::Irpc(_) => self.irpc.resend_due(msg_id, now),
            Order::Compact(_) | Order::Orion(_) | Order::Moteus(_) | Order::Servo(_) => false,
        }
    }

    /// Resends and time-outs of the compact commands due at `now` (after
    /// the iRPC client's have been taken, as the engine orders them).
    pub(crate) fn command_timeouts(&mut self, now: Duration) {
        for (device, ended) in self.compact.timeouts(now) {
            self.tell(Happened::Ended { device, ended });
        }
        for (device, ended) in self.moteus.timeouts(now) {
            self.tell(Happened::Ended { device, ended });
        }
    }

    /// The links' requests due at `now`: the Orion line in flight sent
    /// again or given up.
    pub(crate) fn link_timeouts(&mut self, now: Duration, devices: &dyn Registry) {
        if let Some(done) = self.orion.expire(now) {
            self.orion_done(&done, now, devices);
        }
        self.servo.expire(now);
        self.take_servo_news(devices);
    }

    /// The next bytes for a servo port, and the port (its index in the
    /// map's servo ports).
    pub(crate) fn poll_serial(&mut self) -> Option<(u8, Vec<u8>)> {
        self.servo.poll_transmit()
    }

    /// Bytes from servo port `port`, received at `now`.
    pub(crate) fn handle_serial(
        &mut self,
        now: Duration,
        port: u8,
        bytes: &[u8],
        devices: &dyn Registry,
    ) {
        self.servo.handle_bytes(now, port, bytes);
        self.take_servo_news(devices);
    }

    /// What the servo driver has to tell, told.
    pub(super) fn take_servo_news(&mut self, devices: &dyn Registry) {
        while let Some(news) = self.servo.poll() {
            match news {
                servo::ServoNews::Heard { device, at } => self.tell(Happened::Heard {
                    device,
                    at,
                    up: true,
                }),
                servo::ServoNews::Reading {
                    device,
                    at,
                    reading,
                } => {
                    let Some(j) = devices.get(device) else {
                        continue;
                    };
                    let Device::Servo(t) = j.device else { continue };
                    let ts = unix_ms(self.epoch, at);
                    let feedback = servo::feedback_to_wia(j.name, ts, j.unit, &reading, t.vendor);
                    self.tell(Happened::Reading {
                        device,
                        at,
                        motion: Some((reading.position, reading.velocity)),
                        feedback: Some(Box::new(feedback)),
                    });
                }
                servo::ServoNews::Ended { device, ended } => {
                    self.tell(Happened::Ended { device, ended });
                }
                servo::ServoNews::Bad {
                    port,
                    error,
                    report,
                } => self.tell(Happened::Bad {
                    report: report.map(|suppressed| Event::BadServoPacket {
                        port,
                        error,
                        suppressed,
                    }),
                }),
            }
        }
    }

    /// The links' own lines due at `now`, once the engine has taken what
    /// [`Drivers::link_timeouts`] told: a recovery's stop, and a poll when
    /// none of `devices` on the controller's link is `busy` (a step of
    /// theirs in flight or ready to go).
    pub(crate) fn link_housekeeping(
        &mut self,
        now: Duration,
        devices: &dyn Registry,
        busy: impl Fn(DeviceId) -> bool,
    ) {
        let on_link = |j: &DeviceView<'_>| j.device.link() == Link::Controller;
        let idle = devices.iter().any(|j| on_link(&j))
            && !devices.iter().filter(on_link).any(|j| busy(j.id));
        self.orion.housekeeping(now, idle);
        // Each moteus controller's poll: its held command, or the query.
        self.moteus.polls_due(now);
        self.tell_bounds_news(devices);
    }

    /// What became of each moteus controller's own bounds, told as events.
    pub(super) fn tell_bounds_news(&mut self, devices: &dyn Registry) {
        for (device, news) in self.moteus.bounds_news() {
            let Some(j) = devices.get(device) else {
                continue;
            };
            let unit = |rev: f64| (!rev.is_nan()).then(|| j.unit.from_degrees(rev * 360.0));
            let event = match news {
                moteus_bounds::BoundsNews::Set { min, max } => Event::DeviceBounds {
                    motor_id: j.name.to_owned(),
                    min_position: unit(min),
                    max_position: unit(max),
                    error: None,
                },
                moteus_bounds::BoundsNews::Failed(error) => Event::DeviceBounds {
                    motor_id: j.name.to_owned(),
                    min_position: None,
                    max_position: None,
                    error: Some(error),
                },
            };
            self.tell(Happened::Event(event));
        }
    }

    /// One line from the Orion controller, received at `now`.
    pub(crate) fn handle_line(
        &mut self,
        now: Duration,
        line: &str,
        devices: &dyn Registry,
        map: &BusMap,
    ) {
        // Its motors held offline (it fell silent): heard again, it is
        // made safe and known before they are online.
        let offline = devices
            .iter()
            .any(|j| j.device.link() == Link::Controller && !j.online);
        let output = match self.orion.read(now, line, offline) {
            Ok(o) => o,
            Err(bad) => return self.orion_bad(bad),
        };
        self.orion_heard(now, devices);
        let applied = self
            .orion
            .apply(now, &output, map, unix_ms(self.epoch, now));
        if let Some(bad) = applied.bad {
            return self.orion_bad(bad);
        }
        if let Some((first, reported)) = applied.beacon {
            if reported {
                self.tell(Happened::Event(Event::OrionBeacon { first }));
            }
            self.orion_heard(now, devices);
            if first {
                self.tell(Happened::MayGo {
                    devices: orion_devices(devices),
                });
            }
        }
        for f in applied.feedback {
            let Some(j) = devices.iter().find(|j| j.name == f.motor_id) else {
                continue;
            };
            let Device::Orion(motor) = j.device else {
                continue;
            };
            let degrees = j.unit.to_degrees(f.position);
            let motion = match motor.quantity() {
                Quantity::PositionDegrees => (degrees, 0.0),
                Quantity::Speed | Quantity::Actuator => (0.0, f.velocity),
            };
            self.tell(Happened::Reading {
                device: j.id,
                at: now,
                motion: Some(motion),
                feedback: Some(Box::new(f)),
            });
        }
        if let Some(done) = applied.done {
            self.orion_done(&done, now, devices);
        }
        if applied.recovered {
            // Stopped and known: online again once what came before is
            // taken, nothing resumed.
            self.queued.push_back(Queued::EndOrionRecovery { at: now });
        }
    }

    /// A line from the Orion controller that could not be read (too long,
    /// not UTF-8), at `now`: reported like a bad line.
    pub(crate) fn handle_unreadable(&mut self, now: Duration, reason: &str) {
        let bad = self.orion.unreadable(now, reason);
        self.orion_bad(bad);
    }

    /// The link to the Orion controller ended at `now` (`error` says how):
    /// its motors are offline, and what was in flight has an unknown
    /// outcome. Whether it was up: nothing happens when it was lost
    /// already.
    pub(crate) fn link_lost(&mut self, now: Duration, error: &str, devices: &dyn Registry) -> bool {
        let Some(in_flight) = self.orion.link_lost(now) else {
            return false;
        };
        self.tell(Happened::Event(Event::OrionLinkLost {
            error: error.to_owned(),
        }));
        if let Some(done) = in_flight {
            self.orion_done(&done, now, devices);
        }
        self.tell(Happened::LinkLost {
            devices: orion_devices(devices),
            offline: format!("the link to the Orion controller is lost: {error}"),
            arrival: "the link to the Orion controller is lost".to_owned(),
        });
        true
    }

    /// The next thing to tell the engine. `map` and `devices`: the
    /// engine's, as they are now (an iRPC joint's feedback builds on its
    /// last).
    pub(crate) fn poll(&mut self, map: &BusMap, devices: &dyn Registry) -> Option<Happened> {
        self.take_servo_news(devices);
        loop {
            match self.queued.pop_front() {
                Some(Queued::Tell(h)) => return Some(h),
                Some(Queued::EndOrionRecovery { at }) => {
                    self.orion.end_recovery();
                    self.orion_heard(at, devices);
                }
                Some(Queued::CompactAck {
                    device,
                    at,
                    stopped,
                }) => {
                    // An emergency stop in flight waits for a record that
                    // shows it (sent again at its time-out otherwise).
                    if !stopped && self.compact.in_flight(device).is_some_and(compact::is_stop) {
                        continue;
                    }
                    if let Some(ended) = self.compact.acknowledged(device, at) {
                        return Some(Happened::Ended { device, ended });
                    }
                }
                Some(Queued::MoteusAck { device, at }) => {
                    if let Some(ended) = self.moteus.acknowledged(device, at) {
                        return Some(Happened::Ended { device, ended });
                    }
                }
                None => {
                    let event = self.irpc.poll_event()?;
                    // The first thing it tells is told now (nothing is
                    // queued before it); the rest wait their turn.
                    let mut first = None;
                    let queued = &mut self.queued;
                    let by_node = &self.by_node;
                    irpc::tell(event, map, devices, by_node, self.epoch, |h| {
                        if first.is_none() {
                            first = Some(h);
                        } else {
                            queued.push_back(Queued::Tell(h));
                        }
                    });
                    if first.is_some() {
                        return first;
                    }
                }
            }
        }
    }

    pub(super) fn tell(&mut self, h: Happened) {
        self.queued.push_back(Queued::Tell(h));
    }

    /// A moteus controller's reply, device `ji`'s, at `now`: heard; its
    /// own stop if it just stopped itself (a fault by name, its
    /// watchdog); its reading; its command in flight acknowledged.
    pub(super) fn moteus_reply(
        &mut self,
        now: Duration,
        frame: &Frame,
        ji: DeviceId,
        devices: &dyn Registry,
    ) {
        let Some(j) = devices.get(ji) else { return };
        if frame.data().first() == Some(&motorwire_moteus::diagnostic::SERVER_DATA) {
            // Its diagnostic stream's answer: heard, and read for its
            // bounds; it reports no register and acknowledges nothing.
            match motorwire_moteus::diagnostic::decode(frame.id().raw(), frame.data()) {
                Ok(answer) => {
                    self.tell(Happened::Heard {
                        device: ji,
                        at: now,
                        up: true,
                    });
                    self.moteus.diagnostic_answer(ji, now, &answer);
                    self.tell_bounds_news(devices);
                }
                Err(e) => self.tell(Happened::Bad {
                    report: Some(Event::BadFrame {
                        can_id: frame.id().to_string(),
                        error: e.to_string(),
                    }),
                }),
            }
            return;
        }
        let reply = match moteus::reply(frame).and_then(moteus::plausible) {
            Ok(r) => r,
            Err(error) => {
                return self.tell(Happened::Bad {
                    report: Some(Event::BadFrame {
                        can_id: frame.id().to_string(),
                        error: error.to_string(),
                    }),
                });
            }
        };
        self.tell(Happened::Heard {
            device: ji,
            at: now,
            up: true,
        });
        if self.moteus.observe(ji, &reply)
            && let Some((reason, code)) = moteus::stopped_itself(&reply)
        {
            self.tell(Happened::StoppedItself {
                device: ji,
                at: now,
                reason,
                code,
            });
        }
        let ts = unix_ms(self.epoch, now);
        let feedback = moteus::feedback_to_wia(j.name, ts, j.unit, &reply);
        self.tell(Happened::Reading {
            device: ji,
            at: now,
            motion: moteus::motion(&reply),
            feedback: Some(Box::new(feedback)),
        });
        self.queued.push_back(Queued::MoteusAck {
            device: ji,
            at: now,
        });
    }

    /// Every Orion motor heard at `at`, online if the link is up.
    pub(super) fn orion_heard(&mut self, at: Duration, devices: &dyn Registry) {
        let up = self.orion.up();
        for device in orion_devices(devices) {
            self.tell(Happened::Heard { device, at, up });
        }
    }

    /// A line of the controller's ended: each device whose step it carried
    /// is done, and what waits for the controller may go.
    pub(super) fn orion_done(&mut self, done: &orion::Done, now: Duration, devices: &dyn Registry) {
        let ended = done.ended(now);
        for &device in &done.joints {
            self.tell(Happened::Ended {
                device,
                ended: ended.clone(),
            });
        }
        self.tell(Happened::MayGo {
            devices: orion_devices(devices),
        });
    }

    pub(super) fn orion_bad(&mut self, bad: orion::BadLine) {
        let report = bad.report.map(|suppressed| Event::BadOrionLine {
            error: bad.error,
            suppressed,
        });
        self.tell(Happened::Bad { report });
    }
}

/// The Orion controller's motors among `devices`.
pub(super) fn orion_devices(devices: &dyn Registry) -> Vec<DeviceId> {
    devices
        .iter()
        .filter(|j| j.device.link() == Link::Controller)
        .map(|j| j.id)
        .collect()
}
