//! Replicas sharing their work through Redis (`cluster.redis_url`): the
//! transport only; what a replica does with what it receives is
//! `service::replicas`.
//!
//! # What travels, and where
//! - **Tile parts.** Every record set and rendered pass a replica computes
//!   for a reproducible tile (`service::tile_store`) is added to the stream
//!   `{prefix}:parts:{release}` as one entry: field `e` holds the part framed
//!   as in the tile log (`cache::log::encode_entry`, checksummed) and field
//!   `o` the replica that sent it. The stream is trimmed to about
//!   `cluster.shared_parts` entries. The release is in the name because a
//!   part's key is only meaningful to the release that computed it.
//! - **Posted scenes.** The scene as posted, assets included
//!   (`Posted::encode`), under `{prefix}:scene:{id}`, and an event in the
//!   stream `{prefix}:scenes` (`op` = `put` or `delete`, `id`, `digest`,
//!   `o`).
//!
//! With `cluster.secret` set, each part, scene and scene event carries a
//! BLAKE3 hash keyed by a key derived from the secret (field `m`; a scene's
//! value is `hash \n blob`), and whatever lacks a valid one is refused and
//! counted (`refused_unsigned`): writing to Redis is then not enough to make
//! replicas serve a forged tile or forget a scene. Without it, Redis's
//! content is trusted as it is.
//!
//! Each replica reads both streams from their start when it starts, then
//! follows them with a blocking `XREAD` on a connection of its own (a
//! blocked read would stall other commands on a shared one).
//!
//! # When Redis is down
//! Every command has a short timeout. A failure marks the store
//! disconnected (`/health` says `"connected": false` with the error, the
//! gauge [`SHARED_STORE_CONNECTED`] drops to 0), and the service goes on
//! from its own stores: parts computed meanwhile wait in a bounded outbox
//! and are dropped once it is full (counted), a scene posted meanwhile
//! stays on its replica, and the follower retries every second, resuming
//! after the last entry it read.

use std::sync::Arc;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Duration;

use redis::aio::{ConnectionManager, ConnectionManagerConfig};
use redis::streams::StreamReadReply;
use redis::{AsyncConnectionConfig, Client, RedisError};
use serde::Serialize;
use tokio::sync::mpsc;
use utoipa::ToSchema;

use super::config::ClusterConfig;

/// Gauge: 1 while the last Redis command succeeded, 0 after a failure.
pub const SHARED_STORE_CONNECTED: &str = "bmc_shared_store_connected";
/// Counter: tile parts sent to the other replicas.
pub const SHARED_PARTS_PUBLISHED: &str = "bmc_shared_parts_published_total";
/// Counter: tile parts from other replicas merged into this one's store.
pub const SHARED_PARTS_MERGED: &str = "bmc_shared_parts_merged_total";
/// Counter: tile parts not shared because the outbox was full.
pub const SHARED_PARTS_DROPPED: &str = "bmc_shared_parts_dropped_total";
/// Counter: failed Redis commands.
pub const SHARED_STORE_ERRORS: &str = "bmc_shared_store_errors_total";

/// Longest wait for one command (a blocking read waits [`FOLLOW_BLOCK`] more).
const COMMAND_TIMEOUT: Duration = Duration::from_secs(2);
/// How long one blocking read waits for new entries.
const FOLLOW_BLOCK: Duration = Duration::from_secs(2);
/// Pause before the follower tries again after a failure.
const RETRY_AFTER: Duration = Duration::from_secs(1);
/// Entries read per `XREAD`.
const READ_BATCH: usize = 64;
/// Parts waiting to be sent; more are dropped (module docs).
const OUTBOX: usize = 1024;
/// Scene events kept in their stream (a scene's blob stays under its own key).
const SCENE_EVENTS: usize = 10_000;

/// What other replicas shared, as the follower reads it.
#[derive(Debug)]
pub enum SharedEvent {
    /// A framed tile part (`cache::log` entry).
    Part(Vec<u8>),
    /// Scene `id` was posted (or replaced) with content `digest` (hex).
    ScenePosted { id: String, digest: String },
    /// Scene `id` was deleted.
    SceneDeleted { id: String },
}

/// What `/health` reports about sharing.
#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct SharedStoreStatus {
    /// Whether the last command reached Redis.
    pub connected: bool,
    /// The last failure, while disconnected.
    pub last_error: Option<String>,
    /// Tile parts sent, merged from others, and not sent (outbox full).
    pub parts_published: u64,
    pub parts_merged: u64,
    pub parts_dropped: u64,
    /// Scenes taken from other replicas.
    pub scenes_adopted: u64,
    /// Parts, scenes and scene events refused for want of a valid
    /// `cluster.secret` hash.
    pub refused_unsigned: u64,
}

/// The queue of tile parts waiting to be shared ([`SharedStore::outbox`]).
pub struct Outbox {
    sender: mpsc::Sender<Vec<u8>>,
    store: Arc<SharedStore>,
}

impl Outbox {
    /// Queues a framed part, or drops it (counted) when the queue is full:
    /// sharing is an optimisation, never a reason to wait.
    pub fn send(&self, framed: Vec<u8>) {
        if self.sender.try_send(framed).is_err() {
            self.store.dropped.fetch_add(1, Ordering::Relaxed);
            metrics::counter!(SHARED_PARTS_DROPPED).increment(1);
        }
    }
}

/// BLAKE3 keyed by `key` over `parts`, each prefixed by its length so that
/// no part can be shifted into the next.
fn keyed_hash(key: &[u8; 32], parts: &[&[u8]]) -> blake3::Hash {
    let mut hasher = blake3::Hasher::new_keyed(key);
    for part in parts {
        hasher.update(&(part.len() as u64).to_le_bytes());
        hasher.update(part);
    }
    hasher.finalize()
}

/// Derivation context of the key `cluster.secret` gives (BLAKE3 `derive_key`).
const SECRET_CONTEXT: &str = "bmc-irradiance 2026-12 cluster items";

/// A connection to the Redis the replicas share (module docs).
pub struct SharedStore {
    client: Client,
    commands: ConnectionManager,
    prefix: String,
    /// The two streams: tile parts of this release, and scene events.
    parts_key: String,
    scenes_key: String,
    /// This process, so the follower skips what it sent itself.
    origin: String,
    shared_parts: u64,
    connected: AtomicBool,
    last_error: Mutex<Option<String>>,
    published: AtomicU64,
    merged: AtomicU64,
    dropped: AtomicU64,
    adopted: AtomicU64,
    /// The key every item sent is hashed with (`cluster.secret`), if any.
    key: Option<[u8; 32]>,
    refused: AtomicU64,
}

impl SharedStore {
    /// The store `config` names, or `None` when `redis_url` is empty. No
    /// connection is made yet (Redis may come up later); must be called
    /// within the Tokio runtime.
    pub fn connect(config: &ClusterConfig) -> Result<Option<Arc<SharedStore>>, RedisError> {
        if config.redis_url.is_empty() {
            return Ok(None);
        }
        let client = Client::open(config.redis_url.as_str())?;
        let manager = ConnectionManagerConfig::new()
            .set_connection_timeout(Some(COMMAND_TIMEOUT))
            .set_response_timeout(Some(COMMAND_TIMEOUT))
            .set_number_of_retries(1);
        let commands = ConnectionManager::new_lazy_with_config(client.clone(), manager)?;
        let origin = format!("{}-{:016x}", std::process::id(), rand::random::<u64>());
        metrics::gauge!(SHARED_STORE_CONNECTED).set(0.0);
        Ok(Some(Arc::new(SharedStore {
            client,
            commands,
            prefix: config.redis_prefix.clone(),
            parts_key: format!(
                "{}:parts:{}",
                config.redis_prefix,
                env!("CARGO_PKG_VERSION")
            ),
            scenes_key: format!("{}:scenes", config.redis_prefix),
            origin,
            shared_parts: config.shared_parts,
            connected: AtomicBool::new(false),
            last_error: Mutex::new(None),
            published: AtomicU64::new(0),
            merged: AtomicU64::new(0),
            dropped: AtomicU64::new(0),
            adopted: AtomicU64::new(0),
            key: (!config.secret.is_empty())
                .then(|| blake3::derive_key(SECRET_CONTEXT, config.secret.as_bytes())),
            refused: AtomicU64::new(0),
        })))
    }

    fn scene_key(&self, id: &str) -> String {
        format!("{}:scene:{id}", self.prefix)
    }

    pub fn status(&self) -> SharedStoreStatus {
        SharedStoreStatus {
            connected: self.connected.load(Ordering::Relaxed),
            last_error: self
                .last_error
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .clone(),
            parts_published: self.published.load(Ordering::Relaxed),
            parts_merged: self.merged.load(Ordering::Relaxed),
            parts_dropped: self.dropped.load(Ordering::Relaxed),
            scenes_adopted: self.adopted.load(Ordering::Relaxed),
            refused_unsigned: self.refused.load(Ordering::Relaxed),
        }
    }

    /// Whether what is sent is signed (`cluster.secret` is set).
    pub fn signs(&self) -> bool {
        self.key.is_some()
    }

    /// The keyed hash of `parts`, hex, or "" without a secret.
    fn seal(&self, parts: &[&[u8]]) -> String {
        self.key.as_ref().map_or_else(String::new, |key| {
            keyed_hash(key, parts).to_hex().to_string()
        })
    }

    /// Whether `seal` is the hash of `parts` (always, without a secret);
    /// counts a refusal.
    fn sealed(&self, seal: Option<&str>, parts: &[&[u8]]) -> bool {
        let Some(key) = &self.key else {
            return true;
        };
        let expected = keyed_hash(key, parts);
        // `blake3::Hash` compares in constant time.
        let valid = seal
            .and_then(|s| blake3::Hash::from_hex(s).ok())
            .is_some_and(|h| h == expected);
        if !valid {
            self.refused.fetch_add(1, Ordering::Relaxed);
            tracing::warn!("refused an item from Redis without a valid cluster.secret hash");
        }
        valid
    }

    /// Counts parts merged from other replicas.
    pub fn count_merged(&self, parts: u64) {
        self.merged.fetch_add(parts, Ordering::Relaxed);
        metrics::counter!(SHARED_PARTS_MERGED).increment(parts);
    }

    /// Counts a scene taken from another replica.
    pub fn count_adopted(&self) {
        self.adopted.fetch_add(1, Ordering::Relaxed);
    }

    /// Records the outcome of a command in the status and metrics.
    fn note<T>(&self, what: &str, result: Result<T, String>) -> Option<T> {
        match result {
            Ok(value) => {
                if !self.connected.swap(true, Ordering::Relaxed) {
                    tracing::info!("shared store connected");
                    metrics::gauge!(SHARED_STORE_CONNECTED).set(1.0);
                }
                *self.last_error.lock().unwrap_or_else(|p| p.into_inner()) = None;
                Some(value)
            }
            Err(err) => {
                if self.connected.swap(false, Ordering::Relaxed) {
                    tracing::warn!(%err, what, "shared store unreachable; serving from this replica's own stores");
                }
                metrics::gauge!(SHARED_STORE_CONNECTED).set(0.0);
                metrics::counter!(SHARED_STORE_ERRORS).increment(1);
                *self.last_error.lock().unwrap_or_else(|p| p.into_inner()) =
                    Some(format!("{what}: {err}"));
                None
            }
        }
    }

    /// Runs one command with [`COMMAND_TIMEOUT`].
    async fn run<T: redis::FromRedisValue>(&self, what: &str, cmd: &redis::Cmd) -> Option<T> {
        let mut connection = self.commands.clone();
        let result = tokio::time::timeout(COMMAND_TIMEOUT, cmd.query_async::<T>(&mut connection))
            .await
            .map_err(|_| "timed out".to_owned())
            .and_then(|r| r.map_err(|e| e.to_string()));
        self.note(what, result)
    }

    /// Where the tile store sends the parts it computes: a bounded queue
    /// drained by a task that adds them to the parts stream.
    pub fn outbox(self: &Arc<Self>) -> Outbox {
        let (sender, mut receiver) = mpsc::channel::<Vec<u8>>(OUTBOX);
        let store = Arc::downgrade(self);
        tokio::spawn(async move {
            while let Some(framed) = receiver.recv().await {
                let Some(store) = store.upgrade() else { break };
                let mut cmd = redis::cmd("XADD");
                let seal = store.seal(&[&framed]);
                cmd.arg(&store.parts_key)
                    .arg("MAXLEN")
                    .arg("~")
                    .arg(store.shared_parts)
                    .arg("*")
                    .arg("o")
                    .arg(&store.origin)
                    .arg("e")
                    .arg(framed)
                    .arg("m")
                    .arg(seal);
                if store
                    .run::<String>("sending a tile part", &cmd)
                    .await
                    .is_some()
                {
                    store.published.fetch_add(1, Ordering::Relaxed);
                    metrics::counter!(SHARED_PARTS_PUBLISHED).increment(1);
                }
            }
        });
        Outbox {
            sender,
            store: self.clone(),
        }
    }

    /// Shares scene `id` as posted (`blob`, `Posted::encode`) with content
    /// `digest`; false when Redis could not be reached.
    pub async fn put_scene(&self, id: &str, digest: &str, blob: Vec<u8>) -> bool {
        let mut set = redis::cmd("SET");
        let seal = self.seal(&[id.as_bytes(), &blob]);
        set.arg(self.scene_key(id))
            .arg([seal.as_bytes(), b"\n", &blob].concat());
        if self.run::<()>("sharing a scene", &set).await.is_none() {
            return false;
        }
        self.scene_event("put", id, digest).await
    }

    /// Whether Redis holds a scene `id` another replica posted (false when
    /// it cannot be reached: this replica then knows only its own).
    pub async fn has_scene(&self, id: &str) -> bool {
        let mut exists = redis::cmd("EXISTS");
        exists.arg(self.scene_key(id));
        self.run::<u32>("looking up a shared scene", &exists)
            .await
            .is_some_and(|n| n > 0)
    }

    /// Tells the other replicas that scene `id` is gone.
    pub async fn delete_scene(&self, id: &str) -> bool {
        let mut del = redis::cmd("DEL");
        del.arg(self.scene_key(id));
        self.run::<()>("deleting a shared scene", &del)
            .await
            .is_some()
            && self.scene_event("delete", id, "").await
    }

    async fn scene_event(&self, op: &str, id: &str, digest: &str) -> bool {
        let mut cmd = redis::cmd("XADD");
        let seal = self.seal(&[op.as_bytes(), id.as_bytes(), digest.as_bytes()]);
        cmd.arg(&self.scenes_key)
            .arg("MAXLEN")
            .arg("~")
            .arg(SCENE_EVENTS)
            .arg("*")
            .arg("o")
            .arg(&self.origin)
            .arg("op")
            .arg(op)
            .arg("id")
            .arg(id)
            .arg("digest")
            .arg(digest)
            .arg("m")
            .arg(seal);
        self.run::<String>("announcing a scene", &cmd)
            .await
            .is_some()
    }

    /// Scene `id` as another replica posted it, if Redis holds it.
    pub async fn scene(&self, id: &str) -> Option<Vec<u8>> {
        let mut get = redis::cmd("GET");
        get.arg(self.scene_key(id));
        let stored = self
            .run::<Option<Vec<u8>>>("reading a shared scene", &get)
            .await
            .flatten()?;
        // `seal \n blob` (the seal empty without a secret).
        let at = stored.iter().position(|&b| b == b'\n')?;
        let (seal, blob) = (&stored[..at], &stored[at + 1..]);
        let seal = std::str::from_utf8(seal).ok();
        self.sealed(seal, &[id.as_bytes(), blob])
            .then(|| blob.to_vec())
    }

    /// Follows both streams from their start (module docs), handing what
    /// other replicas shared to `apply` one batch at a time, until the
    /// returned task is aborted.
    pub fn follow<F, Fut>(self: &Arc<Self>, apply: F) -> tokio::task::JoinHandle<()>
    where
        F: Fn(Vec<SharedEvent>) -> Fut + Send + 'static,
        Fut: Future<Output = ()> + Send,
    {
        let store = self.clone();
        tokio::spawn(async move {
            let mut cursors = ["0".to_owned(), "0".to_owned()];
            let config = AsyncConnectionConfig::new()
                .set_connection_timeout(Some(COMMAND_TIMEOUT))
                .set_response_timeout(Some(COMMAND_TIMEOUT + FOLLOW_BLOCK));
            loop {
                let connection = store
                    .client
                    .get_multiplexed_async_connection_with_config(&config)
                    .await
                    .map_err(|e| e.to_string());
                let Some(mut connection) = store.note("connecting the follower", connection) else {
                    tokio::time::sleep(RETRY_AFTER).await;
                    continue;
                };
                let keys = [&store.parts_key, &store.scenes_key];
                loop {
                    let mut cmd = redis::cmd("XREAD");
                    cmd.arg("COUNT")
                        .arg(READ_BATCH)
                        .arg("BLOCK")
                        .arg(FOLLOW_BLOCK.as_millis() as u64)
                        .arg("STREAMS")
                        .arg(&keys)
                        .arg(&cursors);
                    let reply = cmd
                        .query_async::<Option<StreamReadReply>>(&mut connection)
                        .await
                        .map_err(|e| e.to_string());
                    let Some(reply) = store.note("following the shared streams", reply) else {
                        break;
                    };
                    let mut events = Vec::new();
                    for stream in reply.into_iter().flat_map(|r| r.keys) {
                        let which = usize::from(&stream.key != keys[0]);
                        for entry in stream.ids {
                            cursors[which].clone_from(&entry.id);
                            if entry.get::<String>("o").as_deref() == Some(&store.origin) {
                                continue;
                            }
                            if let Some(event) = store.decode_event(which, &entry) {
                                events.push(event);
                            }
                        }
                    }
                    if !events.is_empty() {
                        apply(events).await;
                    }
                }
                tokio::time::sleep(RETRY_AFTER).await;
            }
        })
    }
}

impl SharedStore {
    /// A stream entry as an event (stream 0 holds parts, stream 1 scene
    /// events), if it is well formed and sealed with this cluster's secret.
    fn decode_event(&self, stream: usize, entry: &redis::streams::StreamId) -> Option<SharedEvent> {
        let seal = entry.get::<String>("m");
        if stream == 0 {
            let framed = entry.get::<Vec<u8>>("e")?;
            return self
                .sealed(seal.as_deref(), &[&framed])
                .then_some(SharedEvent::Part(framed));
        }
        let id = entry.get::<String>("id")?;
        let op = entry.get::<String>("op")?;
        let digest = entry.get::<String>("digest").unwrap_or_default();
        if !self.sealed(
            seal.as_deref(),
            &[op.as_bytes(), id.as_bytes(), digest.as_bytes()],
        ) {
            return None;
        }
        match op.as_str() {
            "put" => Some(SharedEvent::ScenePosted { id, digest }),
            "delete" => Some(SharedEvent::SceneDeleted { id }),
            _ => None,
        }
    }
}
