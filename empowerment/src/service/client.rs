//! The client: batched, pipelined requests with deadlines.
//!
//! A request is loaned in shared memory, filled in place and sent; the client then
//! wakes the server's listener. Up to [`MAX_IN_FLIGHT`] requests may be outstanding;
//! their answers are collected in order, each by polling a short while and then
//! blocking on the client's own listener, which the server notifies.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use fulcrum_contracts::msg::{
    self, kind, status, Describe, EmpRequest, EmpResponse, Names, MAX_BATCH, MAX_IN_FLIGHT,
};
use fulcrum_world::{State, World};
use iceoryx2::port::client::Client as IoxClient;
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::client::ClientCreateError;

use super::error::ClientError;
use super::ports::{clean_dead_nodes, event_service, rr_service, Pending, Rr};

/// A connection to a service: batched, pipelined requests with deadlines.
#[derive(Debug)]
pub struct Client {
    _node: Node<ipc::Service>,
    svc: Rr,
    client: IoxClient<ipc::Service, EmpRequest, u128, EmpResponse, ()>,
    /// Wakes the server after each request.
    wake: Notifier<ipc::Service>,
    /// Where the server wakes this client.
    listener: Listener<ipc::Service>,
    /// The listener's id, sent in each request's user header.
    listener_id: u128,
    world_hash: u64,
    describe: Describe,
    /// Requests sent and not yet collected, oldest first, with their sequence numbers.
    in_flight: VecDeque<(Pending, u32)>,
    seq: u32,
    /// How long one request may take before [`ClientError::Timeout`].
    pub timeout: Duration,
    /// How long to poll for an answer before blocking on the listener.
    pub spin: Duration,
    namespace: String,
}

/// The result of one batch: values and per-state statuses.
#[derive(Debug, Clone, PartialEq)]
pub struct Batch {
    /// E in bits per state.
    pub values: Vec<f32>,
    /// Per-state statuses ([`msg::item`]).
    pub status: Vec<u8>,
}

/// What a request asks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ask {
    /// The service's configured table.
    Lookup,
    /// Count a visit of each state; the answer is its visit count so far (as `f32`).
    Visit,
    /// Any tool (index or [`msg::TOOL_ALL`]), object mask and horizon.
    Query {
        /// Tool index or [`msg::TOOL_ALL`].
        tool: i32,
        /// Object mask.
        objects: u32,
        /// Horizon.
        horizon: u32,
    },
}

impl Client {
    /// Connect to the service of `namespace`, waiting for it up to `deadline`, and check
    /// that it serves `world`.
    pub fn connect(
        namespace: &str,
        world: &World,
        deadline: Duration,
    ) -> Result<Client, ClientError> {
        Client::connect_to(namespace, &world.name, world.content_hash(), deadline)
    }

    /// Connect to the service of `namespace` and check that it serves the world (or world
    /// family) named `name` whose content hash is `hash`.
    pub fn connect_to(
        namespace: &str,
        name: &str,
        hash: u64,
        deadline: Duration,
    ) -> Result<Client, ClientError> {
        let t0 = Instant::now();
        let names = Names::new(namespace);
        let node = NodeBuilder::new()
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<ipc::Service>()
            .map_err(|e| ClientError::transport("node", e))?;
        let svc = wait_for_server(&node, &names, namespace, t0, deadline)?;
        let client = svc.client_builder().create().map_err(|e| match e {
            ClientCreateError::ExceedsMaxSupportedClients => ClientError::Full {
                namespace: namespace.to_string(),
                max: svc.static_config().max_clients(),
            },
            e => ClientError::transport("client", e),
        })?;
        let wake_svc = event_service(&node, &names.server_wake)
            .map_err(|e| ClientError::transport("server wake-up event", e))?;
        let wake = wake_svc
            .notifier_builder()
            .create()
            .map_err(|e| ClientError::transport("notifier", e))?;
        let ans_svc = event_service(&node, &names.client_wake)
            .map_err(|e| ClientError::transport("client wake-up event", e))?;
        let listener = ans_svc
            .listener_builder()
            .create()
            .map_err(|e| ClientError::transport("listener", e))?;
        let listener_id = listener.id().value();
        let mut c = Client {
            _node: node,
            svc,
            client,
            wake,
            listener,
            listener_id,
            world_hash: hash,
            describe: Describe::empty(),
            in_flight: VecDeque::new(),
            seq: 0,
            timeout: deadline.max(Duration::from_secs(5)),
            spin: Duration::from_micros(50),
            namespace: namespace.to_string(),
        };
        c.describe = c.fetch_describe()?;
        if c.describe.world_hash != c.world_hash {
            return Err(ClientError::WrongWorld {
                namespace: namespace.to_string(),
                served: msg::get_name(&c.describe.world),
                served_hash: c.describe.world_hash,
                wanted: name.to_string(),
                wanted_hash: c.world_hash,
            });
        }
        Ok(c)
    }

    /// The service's DESCRIBE answer.
    pub fn describe(&self) -> &Describe {
        &self.describe
    }

    fn fetch_describe(&mut self) -> Result<Describe, ClientError> {
        self.send(kind::DESCRIBE, &[], None, 0, 0, 0)?;
        self.receive_with(|r| r.describe)
    }

    /// Send one request (at most [`MAX_BATCH`] states) without waiting for its answer.
    /// At most [`MAX_IN_FLIGHT`] may be outstanding; [`Client::recv`] collects them in
    /// order.
    pub fn submit(&mut self, ask: Ask, states: &[State]) -> Result<(), ClientError> {
        self.submit_on(ask, states, None)
    }

    /// [`Client::submit`] to the service of a world family: `layouts[i]` is the layout
    /// seed of `states[i]` (`None`: a service of one world).
    pub fn submit_on(
        &mut self,
        ask: Ask,
        states: &[State],
        layouts: Option<&[u64]>,
    ) -> Result<(), ClientError> {
        assert!(
            states.len() <= MAX_BATCH && layouts.is_none_or(|l| l.len() == states.len()),
            "a request carries at most {MAX_BATCH} states, with one layout each or none"
        );
        if self.in_flight.len() >= MAX_IN_FLIGHT {
            return Err(ClientError::Ipc(format!(
                "more than {MAX_IN_FLIGHT} requests in flight: collect answers with recv first"
            )));
        }
        match ask {
            Ask::Lookup => self.send(kind::LOOKUP, states, layouts, 0, 0, 0),
            Ask::Visit => self.send(kind::VISIT, states, layouts, 0, 0, 0),
            Ask::Query {
                tool,
                objects,
                horizon,
            } => self.send(kind::QUERY, states, layouts, tool, objects, horizon),
        }
    }

    fn send(
        &mut self,
        k: u32,
        states: &[State],
        layouts: Option<&[u64]>,
        tool: i32,
        objects: u32,
        horizon: u32,
    ) -> Result<(), ClientError> {
        // Packed straight into the loaned sample: no copy on the way.
        let hash = self.world_hash;
        self.send_slots(hash, k, states.len(), tool, objects, horizon, |i| {
            (states[i].to_bytes(), layouts.map_or(0, |l| l[i]))
        })
    }

    /// Send a request made of raw parts, unchecked (for tests and fuzzing: the service
    /// must answer anything with a status). Collect the answer with [`Client::recv`].
    pub fn send_raw(
        &mut self,
        k: u32,
        states: &[[u8; msg::STATE_BYTES]],
        tool: i32,
        objects: u32,
        horizon: u32,
    ) -> Result<(), ClientError> {
        let hash = self.world_hash;
        self.send_slots(hash, k, states.len(), tool, objects, horizon, |i| {
            (states[i], 0)
        })
    }

    /// Send another client's request as it is (its world hash, kind, states), without
    /// waiting: a bridge forwarding requests from another host. Collect the whole
    /// answer with [`Client::recv_response`].
    pub fn forward(&mut self, req: &EmpRequest) -> Result<(), ClientError> {
        let n = (req.count as usize).min(MAX_BATCH);
        if req.count as usize > MAX_BATCH {
            return Err(ClientError::Refused(status::BAD_COUNT));
        }
        self.send_slots(
            req.world_hash,
            req.kind,
            n,
            req.tool,
            req.objects,
            req.horizon,
            |i| (req.states[i], req.layouts[i]),
        )
    }

    /// Wait for the oldest request's whole answer, whatever its status.
    pub fn recv_response(&mut self) -> Result<Box<EmpResponse>, ClientError> {
        self.receive_with(|r| Box::new(*r))
    }

    /// Loan a request, write its header and `n` state slots from `slot`, send it.
    #[allow(clippy::too_many_arguments)]
    fn send_slots(
        &mut self,
        world_hash: u64,
        k: u32,
        n: usize,
        tool: i32,
        objects: u32,
        horizon: u32,
        slot: impl Fn(usize) -> ([u8; msg::STATE_BYTES], u64),
    ) -> Result<(), ClientError> {
        if n > MAX_BATCH || self.in_flight.len() >= MAX_IN_FLIGHT {
            return Err(ClientError::Ipc(format!(
                "at most {MAX_BATCH} states a request and {MAX_IN_FLIGHT} requests in flight"
            )));
        }
        let mut req = self
            .client
            .loan_uninit()
            .map_err(|e| ClientError::transport("loan", e))?;
        self.seq = self.seq.wrapping_add(1);
        *req.user_header_mut() = self.listener_id;
        // SAFETY: the payload lives in shared memory, which is always backed by
        // initialised bytes, and every field of EmpRequest is plain integers or bytes, so
        // any content is a valid value; we write the header and the `count` states the
        // service reads, and leave the unused tail of `states` as it is (no 38 KiB memset
        // per request).
        let req = unsafe {
            let p = req.payload_mut().as_mut_ptr();
            std::ptr::addr_of_mut!((*p).world_hash).write(world_hash);
            std::ptr::addr_of_mut!((*p).kind).write(k);
            std::ptr::addr_of_mut!((*p).count).write(n as u32);
            std::ptr::addr_of_mut!((*p).tool).write(tool);
            std::ptr::addr_of_mut!((*p).horizon).write(horizon);
            std::ptr::addr_of_mut!((*p).objects).write(objects);
            std::ptr::addr_of_mut!((*p).seq).write(self.seq);
            let slots = std::ptr::addr_of_mut!((*p).states) as *mut [u8; msg::STATE_BYTES];
            let layouts = std::ptr::addr_of_mut!((*p).layouts) as *mut u64;
            for i in 0..n {
                let (state, layout) = slot(i);
                slots.add(i).write(state);
                layouts.add(i).write(layout);
            }
            req.assume_init()
        };
        let pending = req.send().map_err(|e| ClientError::transport("send", e))?;
        self.wake
            .notify()
            .map_err(|e| ClientError::transport("notify", e))?;
        self.in_flight.push_back((pending, self.seq));
        Ok(())
    }

    /// Requests sent and not yet collected.
    pub fn in_flight(&self) -> usize {
        self.in_flight.len()
    }

    /// Wait for the oldest request's answer.
    pub fn recv(&mut self) -> Result<Batch, ClientError> {
        self.receive_with(|r| {
            let n = answered(r)?;
            Ok(Batch {
                values: r.values[..n].to_vec(),
                status: r.item_status[..n].to_vec(),
            })
        })?
    }

    /// The oldest request's answer if it has come, without waiting (`None`: not yet).
    pub fn try_recv(&mut self) -> Result<Option<Batch>, ClientError> {
        let Some((pending, seq)) = self.in_flight.front() else {
            return Ok(None);
        };
        loop {
            match pending.receive() {
                Ok(Some(r)) => {
                    let p: &EmpResponse = r.payload();
                    if p.seq != *seq {
                        continue;
                    }
                    let n = answered(p)?;
                    let batch = Batch {
                        values: p.values[..n].to_vec(),
                        status: p.item_status[..n].to_vec(),
                    };
                    drop(r);
                    self.in_flight.pop_front();
                    return Ok(Some(batch));
                }
                Ok(None) => return Ok(None),
                Err(e) => return Err(ClientError::transport("receive", e)),
            }
        }
    }

    /// Wait for the oldest request's answer and copy it into `values` / `status`.
    pub fn recv_into(
        &mut self,
        values: &mut [f32],
        item_status: &mut [u8],
    ) -> Result<usize, ClientError> {
        self.receive_with(|r| {
            let n = answered(r)?;
            values[..n].copy_from_slice(&r.values[..n]);
            item_status[..n].copy_from_slice(&r.item_status[..n]);
            Ok(n)
        })?
    }

    /// Wait for the oldest request's answer and read it with `read`, in the shared
    /// memory it arrived in (only what `read` takes is copied): poll `spin` (yielding the
    /// core between looks: the service may be waiting for it), then block on the
    /// listener, checking every 100 ms that the service is still there.
    fn receive_with<T>(&mut self, read: impl FnOnce(&EmpResponse) -> T) -> Result<T, ClientError> {
        let Some((pending, seq)) = self.in_flight.pop_front() else {
            return Err(ClientError::Ipc("no request in flight".into()));
        };
        let t0 = Instant::now();
        let mut last_check = t0;
        loop {
            match pending.receive() {
                Ok(Some(r)) => {
                    let p: &EmpResponse = r.payload();
                    if p.seq == seq {
                        return Ok(read(p));
                    }
                }
                Ok(None) => {}
                Err(e) => return Err(ClientError::transport("receive", e)),
            }
            let waited = t0.elapsed();
            if waited >= self.timeout {
                self.in_flight.clear();
                return Err(ClientError::Timeout(self.timeout));
            }
            if waited < self.spin {
                std::thread::yield_now();
                continue;
            }
            // Block on our listener; wake now and then to notice a dead service.
            let _ = self.listener.timed_wait(|_| {}, Duration::from_millis(20));
            if last_check.elapsed() >= Duration::from_millis(100) {
                last_check = Instant::now();
                clean_dead_nodes();
                if !pending.is_connected()
                    || pending.number_of_server_connections() == 0
                    || self.svc.dynamic_config().number_of_servers() == 0
                {
                    if let Ok(Some(r)) = pending.receive() {
                        return Ok(read(r.payload()));
                    }
                    self.in_flight.clear();
                    return Err(ClientError::ServiceGone);
                }
            }
        }
    }

    /// E for any number of states, in pipelined batches of `batch` (<= [`MAX_BATCH`]).
    pub fn values(
        &mut self,
        ask: Ask,
        states: &[State],
        batch: usize,
    ) -> Result<Batch, ClientError> {
        let batch = batch.clamp(1, MAX_BATCH);
        let mut out = Batch {
            values: vec![0.0; states.len()],
            status: vec![0; states.len()],
        };
        let chunks: Vec<&[State]> = states.chunks(batch).collect();
        let depth = MAX_IN_FLIGHT.min(4);
        let mut sent = 0;
        let mut done = 0;
        while done < chunks.len() {
            while sent < chunks.len() && self.in_flight.len() < depth {
                self.submit(ask, chunks[sent])?;
                sent += 1;
            }
            let off = done * batch;
            let n = chunks[done].len();
            self.recv_into(&mut out.values[off..off + n], &mut out.status[off..off + n])?;
            done += 1;
        }
        Ok(out)
    }

    /// The namespace.
    pub fn namespace(&self) -> &str {
        &self.namespace
    }
}

/// Open the request-response service of `names` once a server serves it, cleaning up
/// after dead processes once half a second has passed since `t0`;
/// [`ClientError::NoService`] once `deadline` has.
fn wait_for_server(
    node: &Node<ipc::Service>,
    names: &Names,
    namespace: &str,
    t0: Instant,
    deadline: Duration,
) -> Result<Rr, ClientError> {
    loop {
        let ok = rr_service(node, names, None)
            .ok()
            .filter(|s| s.dynamic_config().number_of_servers() > 0);
        if let Some(s) = ok {
            return Ok(s);
        }
        if t0.elapsed() >= deadline {
            return Err(ClientError::NoService {
                namespace: namespace.to_string(),
                waited: deadline,
            });
        }
        if t0.elapsed() > Duration::from_millis(500) {
            clean_dead_nodes();
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// How many states an answer carries, or its refusal.
fn answered(r: &EmpResponse) -> Result<usize, ClientError> {
    if r.status != status::OK {
        return Err(ClientError::Refused(r.status));
    }
    Ok((r.count as usize).min(MAX_BATCH))
}
