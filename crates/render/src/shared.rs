//! What a farm's workers compute once per job and share: the photon maps and SPPM's photon
//! passes. Each is a pure function of the job, so its bytes are the same whoever computes
//! them; a [`SharedPrepass`] (the farm's coordinator, behind the worker) keeps them by name,
//! and says who computes what is not there yet, so that it is computed once.
//!
//! The render crate knows nothing of HTTP: a worker implements the trait.

/// What a name's bytes are, seen from one worker.
pub enum Shared {
    /// Someone computed and published them.
    Ready(Vec<u8>),
    /// Nobody has them and this worker now holds the claim: compute and publish them.
    Yours,
    /// Another worker holds the claim and is computing them.
    Theirs,
}

/// A store of a job's shared pre-passes.
pub trait SharedPrepass: Send + Sync {
    /// The bytes published under `name`, or who should compute them.
    fn fetch(&self, name: &str) -> Shared;
    /// Publishes what the caller computed under a name it claimed.
    fn publish(&self, name: &str, bytes: &[u8]);
}

/// The value published under `name`, or computed here (and published) when this worker holds
/// the claim. While another worker computes it, `idle` is called to do other useful work (it
/// says whether it did any; if not, the wait sleeps a little), and `stop` may end the wait
/// (None). Bytes that do not decode are computed again here, and not published.
pub fn shared_or_built<T>(
    shared: &dyn SharedPrepass,
    name: &str,
    build: impl FnOnce() -> T,
    encode: impl Fn(&T) -> Vec<u8>,
    decode: impl Fn(&[u8]) -> Result<T, String>,
    mut idle: impl FnMut() -> bool,
    stop: &dyn Fn() -> bool,
) -> Option<T> {
    loop {
        match shared.fetch(name) {
            Shared::Ready(bytes) => {
                return Some(decode(&bytes).unwrap_or_else(|e| {
                    eprintln!(
                        "warning: the shared pre-pass '{name}' is unusable ({e}); computing it here"
                    );
                    build()
                }));
            }
            Shared::Yours => {
                let value = build();
                shared.publish(name, &encode(&value));
                return Some(value);
            }
            Shared::Theirs => {
                if stop() {
                    return None;
                }
                if !idle() {
                    std::thread::sleep(std::time::Duration::from_millis(50));
                }
            }
        }
    }
}
