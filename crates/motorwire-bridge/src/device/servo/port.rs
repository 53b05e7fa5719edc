//! A servo port's transactions: a stop's single writes first, then the
//! goals' sync write and the feedback's sync read; statuses matched to
//! what waits for them; what did not come asked again or given up.

use super::*;

/// Whether `cmd` is a stop (torque off, or a hold): written first, as
/// single writes each answered, and cutting a read short.
const fn is_stop(cmd: &ServoCommand) -> bool {
    matches!(cmd, ServoCommand::TorqueOff | ServoCommand::Hold)
}

impl ServoDriver {
    /// Port `k`'s read in progress is cut short when a stop waits that can
    /// be written now: the stop does not wait for statuses, nor for their
    /// retries. (Its own writes are answered, and sent again until they
    /// are: a status cut by it on the wire costs a retry, never the stop.)
    /// A goal's answered writes are cut short likewise, and dropped at once
    /// when the engine gave the goal up.
    pub(super) fn preempt(&mut self, k: usize) {
        let Some(p) = self.ports.get_mut(k) else {
            return;
        };
        let stop_ready = p.servos.iter().any(|s| match s.waiting {
            Some((_, ServoCommand::TorqueOff, _)) => true,
            Some((_, ServoCommand::Hold, _)) => s.present.is_some(),
            _ => false,
        });
        match &p.awaiting {
            Some(Await::Read { .. }) if stop_ready => {}
            Some(Await::Steps(st)) if !is_stop(&st.cmd) && (stop_ready || st.msg.is_none()) => {}
            _ => return,
        }
        // A goal's answered writes cut short wait again behind the stop
        // (the servo's torque as it may now be); dropped when the engine
        // gave the goal up.
        if let Some(Await::Steps(st)) = p.awaiting.take()
            && let Some(msg) = st.msg
            && let Some(s) = p.servos.iter_mut().find(|s| s.device == st.device)
            && s.waiting.is_none()
        {
            s.waiting = Some((msg, st.cmd, st.total));
            s.torque = None;
        }
        p.awaiting = None;
        p.rx.clear();
    }

    /// Port `k`'s next transaction, if it is free: a stop (or a goal that
    /// turns a Dynamixel servo's torque on) as single answered writes;
    /// else the goals' sync write; then the read, when due or when a goal
    /// was written.
    pub(super) fn pump(&mut self, now: Duration, k: usize) {
        let free = self
            .ports
            .get(k)
            .is_some_and(|p| p.awaiting.is_none() && !p.servos.is_empty());
        if !free {
            return;
        }
        self.rearm_sticky(now, k);
        if self.start_steps(now, k) {
            return;
        }
        let wrote = self.sync_goals(now, k);
        self.start_read(now, k, wrote);
    }

    /// The first order of port `k` written as answered writes, if one
    /// waits: stops first. Whether one was started.
    fn start_steps(&mut self, now: Duration, k: usize) -> bool {
        let Some(p) = self.ports.get_mut(k) else {
            return false;
        };
        let protocol = p.protocol;
        self.blast_torque_off(k);
        let Some(p) = self.ports.get_mut(k) else {
            return false;
        };
        let needs_steps = |s: &Servo| match s.waiting {
            Some((_, ServoCommand::TorqueOff, _)) => true,
            Some((_, ServoCommand::Hold, _)) => s.present.is_some(),
            Some((_, ServoCommand::Goal { .. }, _)) => {
                s.target.vendor == ServoVendor::Dynamixel && s.torque != Some(true)
            }
            None => false,
        };
        let pick = p
            .servos
            .iter()
            .position(|s| needs_steps(s) && s.waiting.is_some_and(|w| is_stop(&w.1)))
            .or_else(|| p.servos.iter().position(needs_steps));
        let Some(s) = pick.and_then(|i| p.servos.get_mut(i)) else {
            return false;
        };
        let Some((msg, cmd, attempts)) = s.waiting.take() else {
            return false;
        };
        s.written = None;
        let (device, id) = (s.device, s.target.id);
        // A sticky stop's write again (number 0): nothing to tell of it.
        let msg = (msg != 0).then_some(msg);
        match steps(s, protocol, cmd) {
            Ok((mut packets, torque_after)) => {
                let Some(first) = packets.pop_front() else {
                    return false;
                };
                self.out
                    .push_back((u8::try_from(k).unwrap_or(u8::MAX), first.clone()));
                if let Some(p) = self.ports.get_mut(k) {
                    p.rx.clear();
                    p.awaiting = Some(Await::Steps(Steps {
                        cmd,
                        device,
                        id,
                        msg,
                        current: first,
                        sends: 1,
                        rest: packets,
                        total: attempts.saturating_add(1),
                        torque_after,
                        deadline: now.saturating_add(p.write_wait),
                    }));
                }
                true
            }
            Err(why) => {
                let Some(msg) = msg else {
                    return self.start_steps(now, k);
                };
                self.ended(
                    device,
                    msg,
                    Outcome::Nacked {
                        code: None,
                        why: why.to_string(),
                        already_stopped: false,
                    },
                    attempts,
                );
                // The next order, if any.
                self.start_steps(now, k)
            }
        }
    }

    /// Each stop of port `k` never answered waits again, once a cycle, until
    /// its servo answers it.
    fn rearm_sticky(&mut self, now: Duration, k: usize) {
        let Some(p) = self.ports.get_mut(k) else {
            return;
        };
        let period = p.period;
        for s in &mut p.servos {
            if s.waiting.is_none()
                && now >= s.sticky_next
                && let Some(cmd) = s.sticky
            {
                s.waiting = Some((0, cmd, 0));
                s.sticky_next = now.saturating_add(period);
            }
        }
    }

    /// Every torque off waiting on port `k`, not yet sent so, in one sync
    /// write ahead of their answered writes: every servo's torque goes off
    /// at once, not one after another behind a servo that does not answer.
    fn blast_torque_off(&mut self, k: usize) {
        let Some(p) = self.ports.get_mut(k) else {
            return;
        };
        let mut entries = Vec::new();
        for s in &mut p.servos {
            if let Some((msg, ServoCommand::TorqueOff, _)) = s.waiting
                && s.blasted != Some(msg)
            {
                s.blasted = Some(msg);
                entries.push((s.target.id, vec![0]));
            }
        }
        if entries.is_empty() {
            return;
        }
        let address = motorwire_translate::torque_address(p.vendor);
        let write = Instruction::SyncWrite {
            address,
            length: 1,
            entries,
        };
        if let Ok(bytes) = encode(p.protocol, &write) {
            self.out
                .push_back((u8::try_from(k).unwrap_or(u8::MAX), bytes));
        }
    }

    /// The goals waiting on port `k` (those that need no answered write)
    /// in one sync write, each to be read back. Whether one was written.
    fn sync_goals(&mut self, now: Duration, k: usize) -> bool {
        let Some(p) = self.ports.get_mut(k) else {
            return false;
        };
        let mut entries = Vec::new();
        let mut address = 0;
        let mut refused = Vec::new();
        for s in &mut p.servos {
            let Some((
                msg,
                cmd @ ServoCommand::Goal {
                    position,
                    velocity,
                    acceleration,
                },
                attempts,
            )) = s.waiting
            else {
                continue;
            };
            s.waiting = None;
            match goal_block("", &s.target, position, velocity, acceleration) {
                Ok(b) => {
                    address = b.address;
                    let goal = i64::from(b.position);
                    entries.push((s.target.id, b.data));
                    s.written = Some(Written {
                        msg,
                        cmd,
                        attempts: attempts.saturating_add(1),
                        goal,
                    });
                    if b.torque_included {
                        s.torque = Some(true);
                    }
                }
                // The gate let it through and the calibration did not
                // change since: not reached; said as the servo's refusal.
                Err(e) => refused.push((s.device, msg, attempts, e.to_string())),
            }
        }
        let protocol = p.protocol;
        for (device, msg, attempts, why) in refused {
            let outcome = Outcome::Nacked {
                code: None,
                why,
                already_stopped: false,
            };
            self.ended(device, msg, outcome, attempts);
        }
        let _ = now;
        let Some(Ok(length)) = entries.first().map(|(_, d)| u16::try_from(d.len())) else {
            return false;
        };
        match encode(
            protocol,
            &Instruction::SyncWrite {
                address,
                length,
                entries,
            },
        ) {
            Ok(bytes) => {
                self.out
                    .push_back((u8::try_from(k).unwrap_or(u8::MAX), bytes));
                true
            }
            Err(_) => false,
        }
    }

    /// Port `k`'s sync read of every servo's feedback block, when it is
    /// due, when a goal was written (`wrote`: it is read back) or when a
    /// hold waits for its servo's position.
    fn start_read(&mut self, now: Duration, k: usize, wrote: bool) {
        let Some(p) = self.ports.get_mut(k) else {
            return;
        };
        let holding = p
            .servos
            .iter()
            .any(|s| matches!(s.waiting, Some((_, ServoCommand::Hold, _))));
        if !(wrote || holding || now >= p.next_read) {
            return;
        }
        let (address, length) = feedback_block(p.vendor);
        let ids: Vec<u8> = p.servos.iter().map(|s| s.target.id).collect();
        if let Ok(bytes) = encode(
            p.protocol,
            &Instruction::SyncRead {
                address,
                length,
                ids: ids.clone(),
            },
        ) {
            self.out
                .push_back((u8::try_from(k).unwrap_or(u8::MAX), bytes));
            p.rx.clear();
            p.awaiting = Some(Await::Read {
                ids,
                deadline: now.saturating_add(p.read_wait),
                attempts: 1,
            });
            if now >= p.next_read {
                p.next_read = now.saturating_add(p.period);
            }
        }
    }

    /// A status on port `k`: the answer to the write or the read it waits
    /// for, or a bad packet.
    pub(super) fn status(&mut self, now: Duration, k: usize, status: &Status) {
        let Some(p) = self.ports.get_mut(k) else {
            return;
        };
        let known = p.servos.iter().any(|s| s.target.id == status.id);
        match &p.awaiting {
            Some(Await::Steps(s)) if s.id == status.id => self.step_answered(now, k, status),
            Some(Await::Read { ids, .. }) if ids.contains(&status.id) => {
                self.read_answered(k, status);
            }
            _ if !known => {
                let error = format!(
                    "a status packet from servo {}, which is none of the map's",
                    status.id
                );
                self.bad(k, error);
            }
            // A late answer to what was given up, or noise that checks.
            _ => {
                let error = format!(
                    "a status packet from servo {} that was not asked for",
                    status.id
                );
                self.bad(k, error);
            }
        }
    }

    /// The status of the write port `k` waits for: its next write, or the
    /// order done (a Dynamixel error number: refused).
    fn step_answered(&mut self, now: Duration, k: usize, status: &Status) {
        let Some(p) = self.ports.get_mut(k) else {
            return;
        };
        let refused = p.protocol == Protocol::Dxl2 && status.error & 0x7F != 0;
        let Some(Await::Steps(mut st)) = p.awaiting.take() else {
            return;
        };
        p.rx.clear();
        let heard = ServoNews::Heard {
            device: st.device,
            at: now,
        };
        self.news.push_back(heard);
        if !refused && let Some(next) = st.rest.pop_front() {
            st.current = next.clone();
            st.sends = 1;
            st.total = st.total.saturating_add(1);
            st.deadline = now.saturating_add(p.write_wait);
            p.awaiting = Some(Await::Steps(st));
            self.out
                .push_back((u8::try_from(k).unwrap_or(u8::MAX), next));
            return;
        }
        if !refused && let Some(s) = p.servos.iter_mut().find(|s| s.device == st.device) {
            s.torque = Some(st.torque_after);
            if is_stop(&st.cmd) {
                s.sticky = None;
            }
        }
        let outcome = if refused {
            Outcome::Nacked {
                code: Some(u16::from(status.error & 0x7F)),
                why: format!(
                    "servo {} refused the write with error {:#04x}",
                    st.id, status.error
                ),
                already_stopped: false,
            }
        } else {
            Outcome::Acked
        };
        if let Some(msg) = st.msg {
            self.ended(st.device, msg, outcome, st.total);
        }
    }

    /// One servo's answer to the read port `k` waits for: heard, its
    /// reading, its goal read back.
    fn read_answered(&mut self, k: usize, status: &Status) {
        let retries = self.retries;
        let now = self.now;
        let Some(p) = self.ports.get_mut(k) else {
            return;
        };
        let (_, length) = feedback_block(p.vendor);
        let refused = p.vendor == ServoVendor::Dynamixel && status.error & 0x7F != 0;
        if let Some(Await::Read { ids, .. }) = &mut p.awaiting {
            ids.retain(|id| *id != status.id);
            if ids.is_empty() {
                p.awaiting = None;
                p.rx.clear();
            }
        }
        let Some(s) = p.servos.iter_mut().find(|s| s.target.id == status.id) else {
            return;
        };
        let device = s.device;
        self.news.push_back(ServoNews::Heard { device, at: now });
        let reading = status
            .params
            .get(..usize::from(length))
            .filter(|_| !refused)
            .and_then(|block| read_block(&s.target, block, status.error, s.torque));
        let Some(reading) = reading else {
            let error = format!(
                "servo {} answered the feedback read with error {:#04x} and {} of its {length} bytes",
                status.id,
                status.error,
                status.params.len()
            );
            return self.bad(k, error);
        };
        s.present = Some(reading.raw);
        if s.target.vendor == ServoVendor::Feetech {
            s.torque = reading.torque;
        }
        let told = match s.written.take() {
            // Taken: the servo holds the goal, its torque on.
            Some(w) if reading.goal == Some(w.goal) && reading.torque != Some(false) => {
                Some((w.msg, Outcome::Acked, w.attempts))
            }
            // Not taken (the write was lost): written again, or refused
            // after every try.
            Some(w) if w.attempts <= retries => {
                if s.waiting.is_none() {
                    s.waiting = Some((w.msg, w.cmd, w.attempts));
                }
                None
            }
            Some(w) => Some((
                w.msg,
                Outcome::Nacked {
                    code: None,
                    why: format!(
                        "servo {} did not take the goal after {} writes: it holds goal step {}",
                        status.id,
                        w.attempts,
                        reading
                            .goal
                            .map_or_else(|| "?".to_owned(), |g| g.to_string())
                    ),
                    already_stopped: false,
                },
                w.attempts,
            )),
            None => None,
        };
        self.news.push_back(ServoNews::Reading {
            device,
            at: now,
            reading,
        });
        if let Some((msg, outcome, attempts)) = told {
            self.ended(device, msg, outcome, attempts);
        }
    }

    /// Port `k`'s wait ended at `now` without its status: a write is sent
    /// again, or given up; a read asks the missing servos again, or gives
    /// them up (counted; their goals written again, or timed out).
    pub(super) fn timed_out(&mut self, now: Duration, k: usize) {
        let retries = self.retries;
        let Some(p) = self.ports.get_mut(k) else {
            return;
        };
        p.rx.clear();
        match p.awaiting.take() {
            Some(Await::Steps(mut st)) => {
                if st.sends <= retries {
                    self.retried += 1;
                    st.sends += 1;
                    st.total = st.total.saturating_add(1);
                    st.deadline = now.saturating_add(p.write_wait);
                    self.out
                        .push_back((u8::try_from(k).unwrap_or(u8::MAX), st.current.clone()));
                    p.awaiting = Some(Await::Steps(st));
                } else {
                    self.missed += 1;
                    // A stop is never given up: written again every cycle
                    // until its servo answers, or takes another order.
                    if is_stop(&st.cmd)
                        && let Some(s) = p.servos.iter_mut().find(|s| s.device == st.device)
                        && s.waiting.is_none()
                    {
                        s.sticky = Some(st.cmd);
                    }
                    if let Some(msg) = st.msg {
                        self.ended(st.device, msg, Outcome::TimedOut, st.total);
                    }
                }
            }
            Some(Await::Read { ids, attempts, .. }) => {
                self.read_timed_out(now, k, ids, attempts);
            }
            None => {}
        }
    }

    /// The read of `ids` on port `k`, sent `attempts` times, ended without
    /// their statuses.
    fn read_timed_out(&mut self, now: Duration, k: usize, ids: Vec<u8>, attempts: u8) {
        let retries = self.retries;
        let Some(p) = self.ports.get_mut(k) else {
            return;
        };
        if attempts <= retries {
            let (address, length) = feedback_block(p.vendor);
            let read = Instruction::SyncRead {
                address,
                length,
                ids: ids.clone(),
            };
            if let Ok(bytes) = encode(p.protocol, &read) {
                self.retried += 1;
                self.out
                    .push_back((u8::try_from(k).unwrap_or(u8::MAX), bytes));
                p.awaiting = Some(Await::Read {
                    ids,
                    deadline: now.saturating_add(p.read_wait),
                    attempts: attempts + 1,
                });
                return;
            }
        }
        let mut ended = Vec::new();
        for id in ids {
            self.missed += 1;
            let Some(s) = p.servos.iter_mut().find(|s| s.target.id == id) else {
                continue;
            };
            if let Some(w) = s.written.take() {
                if w.attempts <= retries {
                    // Written again with the next cycle's writes.
                    if s.waiting.is_none() {
                        s.waiting = Some((w.msg, w.cmd, w.attempts));
                    }
                } else {
                    ended.push((s.device, w.msg, w.attempts));
                }
            }
            // A hold whose servo's position is not known and that cannot
            // be read: given up.
            if let Some((msg, ServoCommand::Hold, attempts)) = s.waiting
                && s.present.is_none()
            {
                s.waiting = None;
                ended.push((s.device, msg, attempts.max(1)));
            }
        }
        for (device, msg, attempts) in ended {
            self.ended(device, msg, Outcome::TimedOut, attempts);
        }
    }
}

/// The answered writes of `cmd` for servo `s` (whose torque and position
/// are as last known), and its torque once they are done.
fn steps(
    s: &Servo,
    protocol: Protocol,
    cmd: ServoCommand,
) -> Result<(VecDeque<Vec<u8>>, bool), DeviceError> {
    let id = s.target.id;
    let write = |address: u16, data: Vec<u8>| {
        encode(protocol, &Instruction::Write { id, address, data })
            .map_err(|e| DeviceError::ServoWrite(e.to_string()))
    };
    let torque = motorwire_translate::torque_address(s.target.vendor);
    let block = match cmd {
        ServoCommand::TorqueOff => return Ok((VecDeque::from([write(torque, vec![0])?]), false)),
        ServoCommand::Hold => {
            let raw = s
                .present
                .ok_or_else(|| DeviceError::ServoWrite("its position is not known".to_owned()))?;
            let raw = u32::try_from(raw)
                .map_err(|_| DeviceError::ServoWrite(format!("step {raw} is below 0")))?;
            motorwire_translate::hold_block(&s.target, raw)
                .map_err(|e| DeviceError::ServoWrite(e.to_string()))?
        }
        ServoCommand::Goal {
            position,
            velocity,
            acceleration,
        } => goal_block("", &s.target, position, velocity, acceleration)
            .map_err(|e| DeviceError::ServoWrite(e.to_string()))?,
    };
    let mut out = VecDeque::from([write(block.address, block.data.clone())?]);
    if !block.torque_included && s.torque != Some(true) {
        out.push_back(write(torque, vec![motorwire_translate::TORQUE_ON])?);
        out.push_back(write(block.address, block.data)?);
    }
    Ok((out, true))
}
