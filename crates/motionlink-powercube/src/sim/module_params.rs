//! An emulated module's parameters: what GetExtended reads (computed for the time asked) and what
//! SetExtended writes (limited as the module limits it).

use super::module::{SimModule, SERVO_LAG_S};
use crate::model::{ConfigWord, ModuleKind, Param, Value};

impl SimModule {
    pub(super) fn get(&self, t: f64, param: Param) -> Option<Value> {
        let p = self.pos_at(t);
        let v = self.vel_at(t);
        let ratio = self.inc_ratio();
        let ticks = |x: f64| (x * ratio).round() as i32;
        let f = |x: f64| Value::F32(x as f32);
        let c = &self.cfg;
        use Param as P;
        Some(match param {
            P::DefHomeOffset => f(0.0),
            P::DefGearRatio => f(c.gear_ratio),
            P::DefLinRatio => f(if self.kind() == ModuleKind::Linear { 0.01 } else { 0.0 }),
            P::DefMinPos => f(c.min_pos),
            P::DefMaxPos => f(c.max_pos),
            P::DefMaxDeltaPos => f(c.max_delta_pos),
            P::DefMaxDeltaVel => f(c.max_vel / 2.0),
            P::DefTorqueRatio => f(1.0),
            P::DefCurRatio => f(1.0),
            P::DefMinVel => f(0.0),
            P::DefMaxVel => f(c.max_vel),
            P::DefMinAcc => f(0.0),
            P::DefMaxAcc => f(c.max_acc),
            P::DefMinCur => f(0.0),
            P::DefMaxCur => f(c.max_cur),
            P::DefHomeVel => f(c.home_vel),
            P::DefHomeAcc => f(c.home_acc),
            P::DefCubeSerial => Value::U32(c.serial),
            P::DefConfig => Value::U32(self.default_config.0),
            P::DefPulsesPerTurn => Value::U32(c.pulses_per_turn),
            P::DefCubeVersion => Value::U16(c.version),
            P::DefServiceInterval => Value::U16(1000),
            P::DefBrakeTimeOut => Value::U16(100),
            P::DefAddress => Value::U8(self.address),
            P::DefPrimBaud | P::DefScndBaud => Value::U8(3),
            P::PosCount | P::ActIPos => Value::I32(ticks(p)),
            P::RefPosCount | P::HomeToZeroInc => Value::I32(0),
            P::HomeOffsetInc => Value::I32(ticks(self.home_offset)),
            P::DioSetup => Value::U32(self.dio_word(t).0),
            P::CubeState => Value::U32(self.state_at(t).0),
            P::TargetPosInc => Value::I32(ticks(self.twin(0, self.target_pos))),
            P::TargetVelInc => Value::U32(ticks(self.twin(1, self.target_vel)).unsigned_abs()),
            P::TargetAccInc => Value::U32(ticks(self.twin(2, self.target_acc)).unsigned_abs()),
            P::StepInc => Value::I32(ticks(self.step_target)),
            // A module before version 3.5.00 (manual 7.2): no acknowledge, as for any parameter it does not know.
            P::Config if self.firmware.no_config_word => return None,
            P::Config => Value::U32(self.config.0),
            P::MoveMode => Value::U8(self.move_mode),
            P::IncRatio => f(ratio),
            P::ActPos | P::IPolPos => f(p),
            P::PrevActPos => f(self.prev_pos),
            P::DeltaPos => f(v * SERVO_LAG_S),
            P::MaxDeltaPos => f(self.max_delta_pos),
            P::ActVel | P::IPolVel => f(v),
            P::MinPos => f(self.min_pos),
            P::MaxPos => f(self.max_pos),
            P::MaxVel => f(self.max_vel),
            P::MaxAcc => f(self.max_acc),
            P::MaxCur => f(self.max_cur),
            P::Cur | P::ActFMotorCurrent => f(if self.motion.is_some() { 0.5 + v.abs() } else { 0.1 }),
            P::Setup => Value::U32(self.setup.0),
            P::HomeOffset => f(self.home_offset),
            P::ActIMaxDeltaPos => Value::I32(ticks(self.max_delta_pos)),
            P::ActIMinPos => Value::I32(ticks(self.min_pos)),
            P::ActIMaxPos => Value::I32(ticks(self.max_pos)),
            P::ActIMaxVel => Value::I32(ticks(self.max_vel)),
            P::ActIMaxAcc => Value::I32(ticks(self.max_acc)),
            P::ActIVel | P::ActIIPolVel => Value::I32(ticks(v)),
            P::ActIDeltaPos => Value::I32(ticks(v * SERVO_LAG_S)),
            // A firmware before this parameter: no acknowledge, as for any parameter a module does not know.
            P::ActFPosStateDio if self.firmware.no_pos_state_dio => return None,
            P::ActFPosStateDio => Value::PosStateDio {
                pos: p as f32,
                state: self.state_at(t).short_state(),
                dio: self.dio_word(t).to_dio(),
            },
            P::ActFSavedPos => f(self.saved_pos),
            P::ActFHomeVel => f(c.home_vel),
            P::ActIHomeVel => Value::I32(ticks(c.home_vel)),
            P::ActFPosTime => Value::PosTime { pos: p as f32, time_ms: self.millis(t) as u16 },
            P::ActFScanPosFallEdge | P::ActFScanPosRisgEdge => f(0.0),
            P::ActRawMotorCurrent => Value::U16(100),
            P::ActRawMotorSupply => Value::U16(2400),
            P::ActRawTemp => Value::I16(300),
            P::ActRawLogicSupply => Value::U16(2400),
            P::ActFMotorSupply | P::ActFLogicSupply => f(24.0),
            P::ActFTemp => f(30.0),
            P::DefC0 | P::ActC0 => self.stored(param, Value::I16(20)),
            P::DefDamp | P::ActDamp => self.stored(param, Value::I16(4)),
            P::DefA0 | P::ActA0 => self.stored(param, Value::I16(3)),
            P::DefBurnCount => Value::U8(1),
            P::RawCur => self.stored(param, Value::I16(0)),
            P::ActSyncTime => self.stored(param, Value::U16(0)),
            P::ActMinLogicSupply | P::ActMinMotorSupply => self.stored(param, f(18.0)),
            P::ActMaxLogicSupply | P::ActMaxMotorSupply => self.stored(param, f(30.0)),
            P::ActLogicUndershootTime
            | P::ActLogicOvershootTime
            | P::ActMotorUndershootTime
            | P::ActMotorOvershootTime => self.stored(param, Value::U32(100)),
            P::ActMaxTemp => self.stored(param, f(70.0)),
            P::ActMinTemp => self.stored(param, f(0.0)),
            P::TargetPos | P::TargetVel | P::TargetAcc => return None,
        })
    }

    /// A new lower soft limit: limited to the ROM default range (chapter 12: commanded values are limited);
    /// a limit above the upper one is not applied (the module keeps its old limit), so that
    /// `min_pos <= max_pos` always holds.
    fn set_min_pos(&mut self, p: f64) {
        let p = p.max(self.cfg.min_pos);
        if p <= self.max_pos {
            self.min_pos = p;
        } else {
            tracing::debug!("module {}: MinPos {p} above MaxPos {} ignored", self.address, self.max_pos);
        }
    }

    /// A new upper soft limit; see [`SimModule::set_min_pos`].
    fn set_max_pos(&mut self, p: f64) {
        let p = p.min(self.cfg.max_pos);
        if p >= self.min_pos {
            self.max_pos = p;
        } else {
            tracing::debug!("module {}: MaxPos {p} below MinPos {} ignored", self.address, self.min_pos);
        }
    }

    /// The Inc twin `i` (0 position, 1 velocity, 2 acceleration): `float`, the float target, on a module
    /// that keeps one value behind both; its own value on one that keeps them apart.
    fn twin(&self, i: usize, float: f64) -> f64 {
        if self.firmware.no_twin_mirror {
            self.twins[i]
        } else {
            float
        }
    }

    /// Writes the Inc twin `i`: its own value, or the float target `float` it mirrors.
    fn set_twin(&mut self, i: usize, value: f64) {
        if self.firmware.no_twin_mirror {
            self.twins[i] = value;
        } else {
            match i {
                0 => self.target_pos = value,
                1 => self.target_vel = value,
                _ => self.target_acc = value,
            }
        }
    }

    fn stored(&self, param: Param, default: Value) -> Value {
        self.store.get(&param.id()).copied().unwrap_or(default)
    }

    fn millis(&self, t: f64) -> u64 {
        ((t - self.time_base).max(0.0) * 1000.0) as u64
    }

    /// The module's millisecond counter (since power on or ResetTime).
    pub fn millis_now(&self) -> u64 {
        self.millis(self.t)
    }

    pub(super) fn set(&mut self, _t: f64, param: Param, value: Value) {
        if !param.access().writable() || value.check_type(param).is_err() {
            // A real module ignores what it cannot apply; the acknowledge still comes.
            return;
        }
        let Some(fl) = value.as_f64().filter(|v| v.is_finite()) else {
            // NaN or infinite: nothing to limit it to; ignored the same way.
            return;
        };
        let ratio = self.inc_ratio();
        let c = self.cfg.clone();
        let from_ticks = fl / ratio;
        use Param as P;
        match param {
            P::DioSetup => self.outputs = ((value.as_u32().unwrap_or(0) >> 4) & 0x0F) as u8,
            P::TargetPosInc => self.set_twin(0, from_ticks),
            P::TargetVelInc => self.set_twin(1, from_ticks),
            P::TargetAccInc => self.set_twin(2, from_ticks),
            P::Config => self.config = ConfigWord(value.as_u32().unwrap_or(0)),
            P::MaxDeltaPos => self.max_delta_pos = fl.abs(),
            P::ActIMaxDeltaPos => self.max_delta_pos = from_ticks.abs(),
            P::MinPos => self.set_min_pos(fl),
            P::ActIMinPos => self.set_min_pos(from_ticks),
            P::MaxPos => self.set_max_pos(fl),
            P::ActIMaxPos => self.set_max_pos(from_ticks),
            P::MaxVel => self.max_vel = fl.abs().min(c.max_vel),
            P::ActIMaxVel => self.max_vel = from_ticks.abs().min(c.max_vel),
            P::MaxAcc => self.max_acc = fl.abs().min(c.max_acc),
            P::ActIMaxAcc => self.max_acc = from_ticks.abs().min(c.max_acc),
            P::MaxCur => self.max_cur = fl.abs().min(c.max_cur),
            P::TargetPos => self.target_pos = fl,
            P::TargetVel => self.target_vel = fl.abs(),
            P::TargetAcc => self.target_acc = fl.abs(),
            P::HomeOffset => self.home_offset = fl,
            // Commanded values are limited (chapter 12): RawCur to its range, -500..500 digits.
            P::RawCur => {
                let max = crate::wire::RAW_CUR_MAX;
                let digits = value.as_i32().unwrap_or(0).clamp(i32::from(-max), i32::from(max));
                self.store.insert(param.id(), Value::I16(digits as i16));
            }
            _ => {
                self.store.insert(param.id(), value);
            }
        }
    }
}
