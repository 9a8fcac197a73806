//! Receiving rows from the network in a program: a subscriber on a row key expression (the
//! fused rows of a table, a camera's rows, or wildcards over them) that hands each message,
//! decoded, to a callback.
//!
//! ```no_run
//! use rodtrack_zenoh::net::NetworkOptions;
//! use rodtrack_zenoh::subscriber::RowSubscriber;
//!
//! let net = NetworkOptions {
//!     connect: vec!["tcp/127.0.0.1:7447".into()],
//!     ..NetworkOptions::default()
//! };
//! let sub = RowSubscriber::open(&net, "rodtrack/*/fused/rows", |r| {
//!     if let Ok(m) = r.message {
//!         for row in &m.rows {
//!             println!("frame {} rod {}: {:.3} mm", row.frame, row.rod, row.position_mm);
//!         }
//!     }
//! })?;
//! std::thread::sleep(std::time::Duration::from_secs(10));
//! sub.close();
//! # Ok::<(), rodtrack_zenoh::ZenohError>(())
//! ```

use crate::layout::{decode, Message};
use crate::net::NetworkOptions;
use crate::ZenohError;
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime};
use zenoh::pubsub::Subscriber;
use zenoh::Wait;

/// One message received.
#[derive(Debug)]
pub struct Received<'a> {
    /// The key expression it came on (`rodtrack/<table>/fused/rows`).
    pub key: &'a str,
    /// When the subscriber received it: the system clock (the Unix epoch), read first thing
    /// in zenoh's callback, before decoding.
    pub received: SystemTime,
    /// The message, or why it does not decode.
    pub message: Result<Message, ZenohError>,
}

/// What the subscriber calls for each message.
type OnMessage = Arc<dyn Fn(Received<'_>) + Send + Sync>;

/// A subscriber on row key expressions and its own zenoh session; see the module
/// documentation. Dropped or [closed](RowSubscriber::close), it stops.
pub struct RowSubscriber {
    // Declared before the session so that they are undeclared first.
    subscribers: Vec<Subscriber<()>>,
    session: zenoh::Session,
    on_message: OnMessage,
}

impl RowSubscriber {
    /// Opens a session with `net`'s endpoints (or configuration file) and subscribes to
    /// `key` (a zenoh key expression: `rodtrack/lab/fused/rows`, `rodtrack/*/cam/*/raw`).
    /// `on_message` runs in zenoh's threads, once per message: it should return quickly.
    pub fn open<F>(net: &NetworkOptions, key: &str, on_message: F) -> Result<Self, ZenohError>
    where
        F: Fn(Received<'_>) + Send + Sync + 'static,
    {
        let mut s = RowSubscriber {
            subscribers: Vec::new(),
            session: net.open()?,
            on_message: Arc::new(on_message),
        };
        s.add(key)?;
        Ok(s)
    }

    /// Subscribes to one more key expression, with the same callback.
    pub fn add(&mut self, key: &str) -> Result<(), ZenohError> {
        let on_message = self.on_message.clone();
        let subscriber = self
            .session
            .declare_subscriber(key.to_string())
            .callback(move |sample| {
                let received = SystemTime::now();
                let bytes = sample.payload().to_bytes();
                on_message(Received {
                    key: sample.key_expr().as_str(),
                    received,
                    message: decode(&bytes),
                });
            })
            .wait()
            .map_err(|e| ZenohError::zenoh(format!("declaring a subscriber on {key}"), e))?;
        self.subscribers.push(subscriber);
        Ok(())
    }

    /// Subscribes to the fused rows of `net`'s table (`rodtrack/<table>/fused/rows`).
    pub fn fused<F>(net: &NetworkOptions, on_message: F) -> Result<Self, ZenohError>
    where
        F: Fn(Received<'_>) + Send + Sync + 'static,
    {
        let key = crate::net::fused_key(net.table()?, "rows");
        RowSubscriber::open(net, &key, on_message)
    }

    /// The key expressions subscribed to.
    pub fn keys(&self) -> Vec<&str> {
        self.subscribers
            .iter()
            .map(|s| s.key_expr().as_str())
            .collect()
    }

    /// The session (its other uses: queries, publishers, status subscribers).
    pub fn session(&self) -> &zenoh::Session {
        &self.session
    }

    /// Waits, at most `timeout`, until the session is connected to at least `peers` other
    /// nodes; returns how many it is connected to.
    pub fn wait_for_peers(&self, peers: usize, timeout: Duration) -> usize {
        let until = Instant::now() + timeout;
        loop {
            let n = self.session.info().peers_zid().wait().count();
            if n >= peers || Instant::now() >= until {
                return n;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// Undeclares the subscribers and closes the session.
    pub fn close(self) {
        let RowSubscriber {
            subscribers,
            session,
            ..
        } = self;
        crate::net::close_subscribed(subscribers, session);
    }
}
