//! Requests with their checks and retries, reads of typed values, broadcasts: the steps every longer
//! operation is made of.

use std::time::Duration;

use crate::error::{unexpected, Error};
use crate::model::{
    AxisUnit, Broadcast, ConfigFlag, ConfigWord, CubeState, CubeVersion, ModuleKind, Param, Position, Quantity,
    StateFlag, Value,
};
use crate::session::core::only_watchdog_flag;
use crate::session::ctx::Ctx;
use crate::session::{HaltReport, ModuleInfo, HALT_SETTLE};
use crate::wire::{is_module_address, ACK_OK};
use crate::wire::{Action, Reply, Request};

/// A refusal in an acknowledge's status byte is an error.
fn check_reply(address: u8, request: &Request, reply: Reply) -> Result<Reply, Error> {
    match reply {
        Reply::Set(_, status) | Reply::Motion { status: Some(status), .. } if status != ACK_OK => {
            Err(Error::Refused { address: crate::model::Address::checked(address), request: *request, status })
        }
        r => Ok(r),
    }
}

impl Ctx {
    /// Checks a request before it is sent: the address (1..31), the manual's rules ([`Request::validate`]:
    /// access, value type, finite floats, the MotionID for the acknowledge asked), and, on CAN, no
    /// CONFIGID_MOD_DISABLE_ACK (this client needs acknowledges). Every request goes through here.
    pub fn check(&self, address: u8, request: &Request) -> Result<(), Error> {
        if !is_module_address(address) {
            return Err(Error::InvalidAddress(address));
        }
        request.validate()?;
        if let Request::Set(Param::Config, value) = request {
            let word = value.as_u32().map(ConfigWord);
            if self.core().can && word.is_some_and(|w| w.contains(ConfigFlag::DisableAck)) {
                return Err(Error::NotSupported(
                    "CONFIGID_MOD_DISABLE_ACK: this client needs the acknowledges of its commands".into(),
                ));
            }
        }
        Ok(())
    }

    /// One request, checked before it is sent, its acknowledge checked; reads are retried
    /// ([`Config::read_retries`](crate::session::Config::read_retries)), nothing else is, and not once the
    /// operation is cancelled: the Halt that answers the cancel goes out after one unanswered read, not
    /// after its retries.
    pub async fn request(&self, address: u8, request: Request) -> Result<Reply, Error> {
        self.request_retrying(address, request, false).await
    }

    /// [`Ctx::request`], whose read is asked again also after the operation was cancelled where
    /// `after_cancel` says so: the reads that confirm a stop, which comes after the cancel.
    async fn request_retrying(&self, address: u8, request: Request, after_cancel: bool) -> Result<Reply, Error> {
        self.check(address, &request)?;
        let (attempts, timeout) = {
            let mut core = self.core();
            core.note_request(address, &request);
            if request.starts_motion() {
                core.mark_started(address);
                let now = core.now;
                core.motion_sent.insert(address, now);
            }
            let retries = if request.is_idempotent() { core.config.read_retries } else { 0 };
            (1 + retries, core.config.reply_timeout)
        };
        let mut last = None;
        for attempt in 0..attempts {
            match self.exchange(vec![(address, request)], timeout).await.pop() {
                Some(Ok(reply)) => return check_reply(address, &request, reply),
                Some(Err(e)) if e.retryable() && attempt + 1 < attempts && (after_cancel || !self.cancelled()) => {
                    tracing::debug!("{e}; trying again");
                    last = Some(e);
                }
                Some(Err(e)) => return Err(e),
                None => break,
            }
        }
        Err(last.unwrap_or_else(|| Error::NotSupported("no answer was collected".into())))
    }

    /// Several requests to several modules; on CAN all are sent at once and the acknowledges collected in
    /// any order, on RS232 one after the other. Each is checked as [`Ctx::request`] checks it (one that
    /// breaks the rules gets its error and is not sent; the others are). Reads that fail are retried.
    pub async fn request_many(&self, requests: &[(u8, Request)]) -> Vec<Result<Reply, Error>> {
        let mut results: Vec<Option<Result<Reply, Error>>> = requests.iter().map(|_| None).collect();
        for (i, (address, request)) in requests.iter().enumerate() {
            if let Err(e) = self.check(*address, request) {
                results[i] = Some(Err(e));
                continue;
            }
            self.core().note_request(*address, request);
            if request.starts_motion() {
                let mut core = self.core();
                core.mark_started(*address);
                let now = core.now;
                core.motion_sent.insert(*address, now);
            }
        }
        let (retries, timeout, can) = {
            let core = self.core();
            (core.config.read_retries, core.config.reply_timeout, core.can)
        };
        for attempt in 0..=retries {
            let todo: Vec<usize> = (0..requests.len())
                .filter(|&i| match &results[i] {
                    None => true,
                    Some(Err(e)) => attempt > 0 && e.retryable() && requests[i].1.is_idempotent(),
                    Some(Ok(_)) => false,
                })
                .collect();
            if todo.is_empty() {
                break;
            }
            let batch: Vec<(u8, Request)> = todo.iter().map(|&i| requests[i]).collect();
            let answers = if can {
                self.exchange(batch, timeout).await
            } else {
                let mut answers = Vec::with_capacity(batch.len());
                for r in batch {
                    answers.extend(self.exchange(vec![r], timeout).await);
                }
                answers
            };
            for (&i, answer) in todo.iter().zip(answers) {
                let (address, request) = &requests[i];
                results[i] = Some(answer.and_then(|r| check_reply(*address, request, r)));
            }
        }
        results.into_iter().map(|r| r.unwrap_or_else(|| Err(Error::NotSupported("not sent".into())))).collect()
    }

    /// Reads `param` of every module in `addresses` (on CAN in one round).
    pub async fn read_many(&self, addresses: &[u8], param: Param) -> Vec<Result<Value, Error>> {
        let req = match Request::get(param) {
            Ok(r) => r,
            Err(e) => return addresses.iter().map(|_| Err(Error::Model(e.clone()))).collect(),
        };
        let requests: Vec<(u8, Request)> = addresses.iter().map(|a| (*a, req)).collect();
        self.request_many(&requests)
            .await
            .into_iter()
            .zip(addresses)
            .map(|(r, a)| match r? {
                Reply::Get(_, v) => Ok(v),
                other => Err(unexpected(*a, &req, other)),
            })
            .collect()
    }

    /// The positions of `addresses` (ActPos), on CAN in one round; in rad or m where the session knows
    /// the module's kind, in the module's own unit otherwise.
    pub async fn positions(&self, addresses: &[u8]) -> Vec<Result<Position, Error>> {
        let req = Request::Get(Param::ActPos);
        let values = self.read_many(addresses, Param::ActPos).await;
        let core = self.core();
        values
            .into_iter()
            .zip(addresses)
            .map(|(r, a)| {
                r.and_then(|v| {
                    v.as_f32()
                        .map(|x| Position::native(x).resolved(core.kinds.get(a).copied()))
                        .ok_or_else(|| unexpected(*a, &req, format!("{v:?}")))
                })
            })
            .collect()
    }

    /// Sends a broadcast (never acknowledged). Home and StartMotion count as setting in motion every module
    /// the session knows (the addresses that have answered it); a Halt clears that list on CAN only (on
    /// RS232 the modules may have ignored it).
    pub async fn broadcast(&self, broadcast: Broadcast) -> Result<(), Error> {
        {
            let mut core = self.core();
            // Every module resets, homes or halts: what the setpoints of each cached may no longer hold.
            if matches!(broadcast, Broadcast::Reset | Broadcast::Home | Broadcast::Halt) {
                core.setpoints.clear();
            }
            match broadcast {
                Broadcast::Halt if core.can => core.started.clear(),
                Broadcast::Home | Broadcast::StartMotion => {
                    let known = core.known.clone();
                    for a in known {
                        core.mark_started(a);
                    }
                }
                _ => {}
            }
        }
        let r = self.send_broadcast(broadcast).await;
        if r.is_err() {
            self.core().failed = true;
        }
        r
    }

    /// Reads `param` (refused before sending if it is write-only).
    pub async fn get(&self, address: u8, param: Param) -> Result<Value, Error> {
        let request = Request::get(param)?;
        match self.request(address, request).await? {
            Reply::Get(_, v) => Ok(v),
            other => Err(unexpected(address, &request, other)),
        }
    }

    /// Writes `param` (refused before sending if it is read-only, `value` has another type or is not a
    /// finite number, or, on CAN, it would disable the acknowledges).
    pub async fn set(&self, address: u8, param: Param, value: Value) -> Result<(), Error> {
        let request = Request::set(param, value)?;
        self.request(address, request).await?;
        if param == Param::Config {
            let mut core = self.core();
            let known = core.configs.get(&address).copied().flatten();
            match (known, value.as_u32().map(ConfigWord)) {
                // The watchdog flag alone (arming, disarming): the kind and the rest of the word stand.
                (Some(before), Some(after)) if only_watchdog_flag(before, after) => {
                    core.configs.insert(address, Some(after));
                }
                _ => {
                    core.kinds.remove(&address);
                    core.configs.remove(&address);
                }
            }
        }
        Ok(())
    }

    /// Reads `param` and converts it with `convert`; a value of another type is a corrupt answer.
    pub async fn get_as<T>(
        &self,
        address: u8,
        param: Param,
        convert: impl FnOnce(&Value) -> Option<T>,
    ) -> Result<T, Error> {
        let value = self.get(address, param).await?;
        convert(&value).ok_or_else(|| unexpected(address, &Request::Get(param), format!("{value:?}")))
    }

    /// Reads a float parameter.
    pub async fn get_f32(&self, address: u8, param: Param) -> Result<f32, Error> {
        self.get_as(address, param, Value::as_f32).await
    }

    /// Reads an unsigned parameter.
    pub async fn get_u32(&self, address: u8, param: Param) -> Result<u32, Error> {
        self.get_as(address, param, Value::as_u32).await
    }

    /// The actual position (ActPos), in rad or m if the session knows the module's kind.
    pub async fn position(&self, address: u8) -> Result<Position, Error> {
        let v = self.get_f32(address, Param::ActPos).await?;
        Ok(Position::native(v).resolved(self.known_kind(address)))
    }

    /// The state word (CubeState). A module seen with an error flag or halted has its setpoint cache
    /// dropped.
    pub async fn state(&self, address: u8) -> Result<CubeState, Error> {
        let state = CubeState(self.get_u32(address, Param::CubeState).await?);
        if state.has_fault() || state.contains(StateFlag::Halted) {
            self.core().drop_setpoints(address);
        }
        Ok(state)
    }

    /// The Config word (the module's kind is learnt from it on the way).
    pub async fn config_word(&self, address: u8) -> Result<ConfigWord, Error> {
        let word = ConfigWord(self.get_u32(address, Param::Config).await?);
        self.learn_kind(address, word);
        self.core().configs.insert(address, Some(word));
        Ok(word)
    }

    /// Remembers the kind CONFIGID_MOD_LINEAR of `word` gives module `address`.
    fn learn_kind(&self, address: u8, word: ConfigWord) {
        let kind = if word.contains(ConfigFlag::Linear) { ModuleKind::Linear } else { ModuleKind::Rotary };
        self.core().kinds.insert(address, kind);
    }

    /// The module's kind if the session has read it.
    pub fn known_kind(&self, address: u8) -> Option<ModuleKind> {
        self.core().kinds.get(&address).copied()
    }

    /// Rotary or linear (read once from the Config word, then remembered). A module that gives no
    /// acknowledge for the Config word (parameter 57, "available from module version 3.5.00", manual 7.2)
    /// while it answers DefConfig, the Config word's ROM default, has its kind read from that (one warning).
    pub async fn kind(&self, address: u8) -> Result<ModuleKind, Error> {
        if let Some(k) = self.known_kind(address) {
            return Ok(k);
        }
        match self.config_word(address).await {
            Ok(_) => {}
            Err(e @ Error::Timeout { .. }) => {
                let Ok(word) = self.get_u32(address, Param::DefConfig).await else { return Err(e) };
                self.learn_kind(address, ConfigWord(word));
                self.core().configs.insert(address, None);
                self.core().warn_once(address, "config_word", || {
                    format!(
                        "module {address} does not answer the Config word (parameter 57, from module version \
                         3.5.00): its type is read from DefConfig"
                    )
                });
            }
            Err(e) => return Err(e),
        }
        self.known_kind(address).ok_or_else(|| Error::NotSupported("the module's kind was not kept".into()))
    }

    /// Refuses a quantity whose unit does not fit the module (rad for a linear module, m for a rotary one);
    /// reads the module's kind only if a unit is said (the module's own unit fits any module).
    pub async fn check_units(&self, address: u8, quantities: &[(&'static str, Quantity)]) -> Result<(), Error> {
        if quantities.iter().all(|(_, q)| q.unit() == AxisUnit::ModuleUnit) {
            return Ok(());
        }
        let kind = self.kind(address).await?;
        match quantities.iter().find(|(_, q)| !q.unit().fits(kind)) {
            Some(&(what, value)) => {
                Err(Error::UnitMismatch { address: crate::model::Address::checked(address), kind, what, value })
            }
            None => Ok(()),
        }
    }

    /// Type, version, serial number and state.
    pub async fn info(&self, address: u8) -> Result<ModuleInfo, Error> {
        let version = self
            .get_as(address, Param::DefCubeVersion, |v| match *v {
                Value::U16(v) => Some(CubeVersion(v)),
                _ => None,
            })
            .await?;
        let kind = self.kind(address).await?;
        let serial = self.get_u32(address, Param::DefCubeSerial).await?;
        let state = self.state(address).await?;
        let address = crate::model::Address::new(address)?;
        Ok(ModuleInfo { address, kind, version, serial, state })
    }

    /// A one-byte command.
    pub async fn action(&self, address: u8, action: Action) -> Result<(), Error> {
        self.request(address, Request::Action(action)).await.map(|_| ())
    }

    /// Halt: stops at once; the module stays halted until a reset.
    pub async fn halt(&self, address: u8) -> Result<(), Error> {
        self.action(address, Action::Halt).await?;
        self.core().started.remove(&address);
        Ok(())
    }

    /// Halt, sent again while it is not acknowledged (a Halt may be repeated safely), as often as a read is
    /// asked again (three in all by default), but not after the line itself failed: the last error and how
    /// many Halts were sent, when none was acknowledged.
    pub async fn halt_repeated(&self, address: u8) -> Result<(), (Error, u32)> {
        let attempts = 1 + self.core().config.read_retries;
        let mut sent = 0;
        loop {
            sent += 1;
            match self.halt(address).await {
                Ok(()) => return Ok(()),
                Err(e) if sent < attempts && !matches!(e, Error::Link(_)) => {
                    tracing::info!("module {address}: Halt not acknowledged ({e}); sending it again")
                }
                Err(e) => return Err((e, sent)),
            }
        }
    }

    /// Halt (sent again when it is not acknowledged, as often as a read is asked again: a Halt is
    /// idempotent), then the state until STATE_MOTION is clear (at most [`HALT_SETTLE`]), then the position.
    /// A Halt never acknowledged is an error that says the axis may still be moving.
    pub async fn halt_confirmed(&self, address: u8) -> Result<HaltReport, Error> {
        self.halt_repeated(address).await.map_err(|(e, sent)| Error::HaltUnacknowledged {
            address: crate::model::Address::checked(address),
            sent,
            cause: Box::new(e),
        })?;
        let state = self.at_rest_after_halt(address).await?;
        let position = self.position(address).await?;
        // The kind (the unit of the position) only now: nothing comes before the Halt.
        let kind = self.kind(address).await.map_err(|e| Error::Context {
            context: format!(
                "module {address} halted (confirmed), but its type (and so the unit of its position) cannot be read"
            ),
            source: Box::new(e),
            hint: "",
        })?;
        Ok(HaltReport { kind, state, position: position.in_unit_of(kind) })
    }

    /// After a Halt the module acknowledged: its state, read until STATE_MOTION is clear, for at most
    /// [`HALT_SETTLE`] (each read asked again as any read, also after a cancel: this is the stop that
    /// answers it). The state at rest; [`Error::StillMoving`] if STATE_MOTION was still set then; the read's
    /// error if the state could not be read.
    pub async fn at_rest_after_halt(&self, address: u8) -> Result<CubeState, Error> {
        let start = self.now();
        let period = self.core().config.poll_interval.max(Duration::from_micros(100));
        let request = Request::Get(Param::CubeState);
        loop {
            let state = match self.request_retrying(address, request, true).await? {
                Reply::Get(_, Value::U32(s)) => CubeState(s),
                other => return Err(unexpected(address, &request, other)),
            };
            if !state.contains(StateFlag::Motion) {
                return Ok(state);
            }
            let waited = self.now().saturating_since(start);
            if waited >= HALT_SETTLE {
                return Err(Error::StillMoving { address: crate::model::Address::checked(address), state, waited });
            }
            self.sleep_until(self.now() + period).await;
        }
    }
}
