//! Setpoints over iceoryx2: the shared-memory payload, the publish-subscribe
//! service `cnc/setpoints`, and the cleanup of what crashed processes left.
//!
//! The payload is `#[repr(C)]` with the iceoryx2 type name [`SETPOINT_TYPE_NAME`]
//! so that subscribers in other languages (C, C++, Python through iceoryx2's
//! own packages) open the same service; `docs/daemon.md` gives its layout.

use anyhow::{Context, Result, anyhow};
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use interp_core::{RunState, Setpoint};

/// Default name of the setpoint service.
pub const DEFAULT_SERVICE: &str = "cnc/setpoints";
/// The payload's iceoryx2 type name: subscribers in other languages must use it.
pub const SETPOINT_TYPE_NAME: &str = "interpd::SetpointMsg";
/// Samples a subscriber may keep unread before the oldest is overwritten (a gap
/// it then detects): one second at the default 1 ms period.
pub const SUBSCRIBER_BUFFER: usize = 1024;
/// Subscribers the service admits at once.
pub const MAX_SUBSCRIBERS: usize = 8;

/// One setpoint as published. A mirror of [`interp_core::Setpoint`] plus the
/// publisher's own gapless sequence number (the interpolator's `tick` does not
/// advance while the service waits for `start`, `seq` always does).
#[derive(Debug, Clone, Copy, Default, PartialEq, ZeroCopySend)]
#[type_name("interpd::SetpointMsg")]
#[repr(C)]
pub struct SetpointMsg {
    /// Published samples since the service started, from 1, gapless.
    pub seq: u64,
    /// The interpolator's tick count (`Setpoint::seq`) of this point.
    pub tick: u64,
    /// Machine time `tick · Ts`, s.
    pub time: f64,
    /// X Y Z A B C (mm; rotary axes in degrees).
    pub axes: [f64; 6],
    /// Commanded path speed over the tick that ended here, mm/s.
    pub feed: f64,
    /// Path parameter of the block at this point.
    pub u: f64,
    /// Arc length of the run, mm.
    pub s: f64,
    /// Id of the block the point is on (0 before any block).
    pub block_id: u32,
    /// [`RunState`] as its `u8` value (Idle 0, Running 1, Holding 2, Stopping 3, Done 4, Fault 5).
    pub state: u32,
}

impl SetpointMsg {
    /// The message for interpolator setpoint `sp`, published as number `seq`.
    pub fn new(seq: u64, sp: &Setpoint) -> Self {
        SetpointMsg {
            seq,
            tick: sp.seq,
            time: sp.time,
            axes: sp.axes,
            feed: sp.feed,
            u: sp.u,
            s: sp.s,
            block_id: sp.block_id,
            state: sp.state as u32,
        }
    }

    /// Back to the interpolator's setpoint (`seq` is the tick).
    pub fn setpoint(&self) -> Setpoint {
        Setpoint {
            seq: self.tick,
            time: self.time,
            axes: self.axes,
            feed: self.feed,
            u: self.u,
            s: self.s,
            block_id: self.block_id,
            state: run_state(self.state),
        }
    }
}

/// The [`RunState`] of a published `state` value (unknown values are `Fault`).
pub fn run_state(v: u32) -> RunState {
    match v {
        0 => RunState::Idle,
        1 => RunState::Running,
        2 => RunState::Holding,
        3 => RunState::Stopping,
        4 => RunState::Done,
        _ => RunState::Fault,
    }
}

/// Lower-case name of a state, as the protocol and summaries print it
/// (the one table, `traces::analysis::state_name`).
pub use traces::analysis::state_name;

/// Removes the shared-memory resources of nodes whose process died (a crash,
/// SIGKILL), so that a restarted service can create its ports. Returns how
/// many dead nodes were cleaned.
pub fn remove_dead_nodes() -> usize {
    set_log_level(LogLevel::Error);
    let mut cleaned = 0;
    let r = Node::<ipc::Service>::list(Config::global_config(), |state| {
        if let NodeState::<ipc::Service>::Dead(view) = state
            && view.try_remove_stale_resources().is_ok()
        {
            cleaned += 1;
        }
        CallbackProgression::Continue
    });
    if let Err(e) = r {
        eprintln!("interpd: warning: listing iceoryx2 nodes failed: {e:?}");
    }
    cleaned
}

/// A node that leaves SIGINT/SIGTERM to us (tokio or the RT loop handle them).
pub fn node(name: &str) -> Result<Node<ipc::Service>> {
    // iceoryx2 warns on every start that it found no config file and uses
    // its defaults, which is what we want: keep errors only.
    set_log_level(LogLevel::Error);
    let name: NodeName = name
        .try_into()
        .map_err(|e| anyhow!("invalid iceoryx2 node name {name:?}: {e:?}"))?;
    NodeBuilder::new()
        .name(&name)
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
        .map_err(|e| anyhow!("creating the iceoryx2 node: {e:?}"))
}

type SetpointService =
    iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, SetpointMsg, ()>;

/// Opens (or creates) the setpoint service `service`.
pub fn open_service(node: &Node<ipc::Service>, service: &str) -> Result<SetpointService> {
    let name: ServiceName = service
        .try_into()
        .map_err(|e| anyhow!("invalid service name {service:?}: {e:?}"))?;
    node.service_builder(&name)
        .publish_subscribe::<SetpointMsg>()
        .subscriber_max_buffer_size(SUBSCRIBER_BUFFER)
        .max_subscribers(MAX_SUBSCRIBERS)
        .max_publishers(1)
        .history_size(0)
        .open_or_create()
        .map_err(|e| anyhow!("opening the iceoryx2 service {service:?}: {e:?}"))
}

/// The RT thread's publisher. `publish` loans a sample, writes it and sends it.
#[derive(Debug)]
pub struct SetpointPublisher {
    publisher: Publisher<ipc::Service, SetpointMsg, ()>,
    // Field order: ports before the service and node they belong to.
    _service: SetpointService,
    _node: Node<ipc::Service>,
    seq: u64,
    failures: u64,
}

impl SetpointPublisher {
    /// Creates the node, service and publisher (not on the RT path).
    pub fn new(service: &str) -> Result<Self> {
        let node = node("interpd_rt")?;
        let svc = open_service(&node, service)?;
        let publisher = svc
            .publisher_builder()
            .create()
            .map_err(|e| anyhow!("creating the publisher on {service:?}: {e:?}"))
            .context("is another interpd serving this service name?")?;
        Ok(SetpointPublisher {
            publisher,
            _service: svc,
            _node: node,
            seq: 0,
            failures: 0,
        })
    }

    /// Publishes `sp` as the next sample. A failed loan or send is counted
    /// (and the sequence number still advances, so subscribers see the gap).
    #[inline]
    pub fn publish(&mut self, sp: &Setpoint) -> u64 {
        self.seq += 1;
        let msg = SetpointMsg::new(self.seq, sp);
        let ok = match self.publisher.loan_uninit() {
            Ok(sample) => sample.write_payload(msg).send().is_ok(),
            Err(_) => false,
        };
        if !ok {
            self.failures += 1;
        }
        self.seq
    }

    /// Samples whose loan or send failed.
    pub fn failures(&self) -> u64 {
        self.failures
    }
}

/// A subscriber of the setpoint service with gap accounting.
#[derive(Debug)]
pub struct SetpointSubscriber {
    subscriber: Subscriber<ipc::Service, SetpointMsg, ()>,
    _service: SetpointService,
    node: Node<ipc::Service>,
    last: Option<SetpointMsg>,
    /// Samples missing between received ones (of one publisher).
    pub gaps: u64,
    /// Samples received.
    pub received: u64,
    /// Times the sequence started again from a lower number: a new
    /// publisher (the service restarted), not a gap.
    pub restarts: u64,
    /// Largest distance between the last point before a restart and the
    /// first after it, mm.
    pub restart_jump_mm: f64,
}

impl SetpointSubscriber {
    /// Subscribes to `service`, creating it if no publisher is there yet.
    pub fn new(node_name: &str, service: &str) -> Result<Self> {
        let node = node(node_name)?;
        let svc = open_service(&node, service)?;
        let subscriber = svc
            .subscriber_builder()
            .buffer_size(SUBSCRIBER_BUFFER)
            .create()
            .map_err(|e| anyhow!("creating a subscriber on {service:?}: {e:?}"))?;
        Ok(SetpointSubscriber {
            subscriber,
            _service: svc,
            node,
            last: None,
            gaps: 0,
            received: 0,
            restarts: 0,
            restart_jump_mm: 0.0,
        })
    }

    /// The next sample if one is there; gaps in `seq` are counted, and a
    /// sequence that starts again lower as a restart of the publisher (with
    /// the jump of position across it). The first sample received sets the
    /// baseline (a late subscriber misses the start).
    pub fn try_next(&mut self) -> Result<Option<SetpointMsg>> {
        let Some(sample) = self
            .subscriber
            .receive()
            .map_err(|e| anyhow!("receiving a setpoint: {e:?}"))?
        else {
            return Ok(None);
        };
        let msg = *sample;
        if let Some(last) = self.last {
            if msg.seq <= last.seq {
                // A publisher counts from 1: a lower number is a new one.
                self.restarts += 1;
                let d = (0..3)
                    .map(|i| (msg.axes[i] - last.axes[i]).powi(2))
                    .sum::<f64>()
                    .sqrt();
                self.restart_jump_mm = self.restart_jump_mm.max(d);
            } else {
                self.gaps += msg.seq - last.seq - 1;
            }
        }
        self.last = Some(msg);
        self.received += 1;
        Ok(Some(msg))
    }

    /// Waits up to `timeout` for the node (returns false on a termination request).
    pub fn wait(&self, timeout: core::time::Duration) -> bool {
        self.node.wait(timeout).is_ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::mem::{align_of, offset_of, size_of};

    #[test]
    fn payload_layout_is_the_documented_one() {
        assert_eq!(size_of::<SetpointMsg>(), 104);
        assert_eq!(align_of::<SetpointMsg>(), 8);
        let offsets = [
            offset_of!(SetpointMsg, seq),
            offset_of!(SetpointMsg, tick),
            offset_of!(SetpointMsg, time),
            offset_of!(SetpointMsg, axes),
            offset_of!(SetpointMsg, feed),
            offset_of!(SetpointMsg, u),
            offset_of!(SetpointMsg, s),
            offset_of!(SetpointMsg, block_id),
            offset_of!(SetpointMsg, state),
        ];
        assert_eq!(offsets, [0, 8, 16, 24, 72, 80, 88, 96, 100]);
        // SAFETY: type_name only returns the derive's constant.
        assert_eq!(unsafe { SetpointMsg::type_name() }, SETPOINT_TYPE_NAME);
    }

    #[test]
    fn a_message_carries_the_setpoint_back_and_forth() {
        let sp = Setpoint {
            seq: 42,
            time: 0.042,
            axes: [1.0, -2.0, 3.5, 0.0, 0.0, 0.0],
            feed: 12.5,
            u: 0.25,
            s: 7.0,
            block_id: 9,
            state: RunState::Holding,
        };
        let m = SetpointMsg::new(100, &sp);
        assert_eq!((m.seq, m.tick, m.state), (100, 42, 2));
        assert_eq!(m.setpoint(), sp);
        for s in [
            RunState::Idle,
            RunState::Running,
            RunState::Holding,
            RunState::Stopping,
            RunState::Done,
            RunState::Fault,
        ] {
            assert_eq!(run_state(s as u32), s);
        }
        assert_eq!(run_state(77), RunState::Fault);
    }
}
