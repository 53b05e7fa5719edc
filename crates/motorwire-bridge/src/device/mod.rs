//! The device layer: one driver per dialect under the engine.
//!
//! A driver owns what is particular to its dialect: its encoding (built by
//! pure functions first, queued second, so each is tested with byte
//! vectors alone, as moteus's `make_*`/`set_*` split does), its requests in
//! flight with their acknowledgements and retries, and its feedback
//! decoding into WIA `MotorFeedback`. The engine keeps what is common to
//! every motor: admission, jobs (one request in flight per device,
//! supersede, busy), the gate at send time, the stop and its latch, the
//! deadman, arrival, drain and exit. A driver never decides admission,
//! limits or stops.
//!
//! A driver is a state machine with no access to the engine (quinn's
//! `Connection`, smoltcp's sockets): the engine calls it with the time and
//! what came in, and takes back what it has to send and what ended
//! ([`orion::Done`], [`compact::Ended`]); its tests drive it with lines or
//! frames alone.
//!
//! Where this stands: the compact dialect ([`compact`]) and the Orion arm
//! controller ([`orion`]: its encoding, its link with the beacon, the loss
//! and the stop written first when it comes back, its one line in flight
//! with resends, its polls and its feedback decoding) are drivers; the
//! engine's `orion` module keeps only what Orion motors are to the engine
//! (jobs, the deadman, arrival). The iRPC joints are still driven through
//! `motorwire_can::client::Client`, reached from the engine directly.
//! Moving it here, behind one closed enum of drivers with one match per
//! operation (smoltcp's `enum Socket`), is the rest of this layer's work.
//!
//! Adding a dialect (the recipe the moteus driver follows): a driver file
//! here with its encoding and its requests in flight, its bus map entry
//! (`motorwire_translate::Target`), its simulated device
//! (`motorwire_sim`, attached by [`crate::sim::SimulatedArm`]), and its
//! fixtures; the every-dialect property test in `tests/invariants.rs` then
//! holds it to every invariant the others keep.

pub(crate) mod compact;
pub(crate) mod orion;
