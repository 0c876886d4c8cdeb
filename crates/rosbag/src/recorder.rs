//! [`Recorder`]: the shared, thread-safe handle the node and the CLI record through.

use std::path::Path;
use std::sync::{Arc, Mutex, MutexGuard, Weak};
use std::thread;

use super::qos::Qos;
use super::writer::{BagOptions, BagSummary, BagWriter};
use super::BagError;
use waam_rosmsg::builtin_interfaces::Time;
use waam_rosmsg::RosMessage;

type Shared = Arc<Mutex<Option<BagWriter>>>;

/// Records messages of any [`RosMessage`] type into one bag. Cheap to clone; every clone
/// writes to the same bag. A background thread closes chunks that grow older than
/// [`BagOptions::chunk_age`] even when no message arrives, so a killed process loses at most
/// that much.
#[derive(Clone)]
pub struct Recorder {
    shared: Shared,
}

impl Recorder {
    /// Creates the bag directory `dir` (which must not exist) with default options.
    pub fn create(dir: &Path) -> Result<Recorder, BagError> {
        Recorder::with_options(dir, BagOptions::default())
    }

    pub fn with_options(dir: &Path, options: BagOptions) -> Result<Recorder, BagError> {
        let writer = BagWriter::create(dir, options)?;
        let shared: Shared = Arc::new(Mutex::new(Some(writer)));
        let weak = Arc::downgrade(&shared);
        // Checked ten times per chunk age, so a chunk is closed at most 10 % after it is due.
        let period = (options.chunk_age / 10).max(std::time::Duration::from_millis(10));
        thread::Builder::new()
            .name("bag-flush".into())
            .spawn(move || flush_loop(weak, period))
            .map_err(|source| BagError::Io {
                path: dir.to_path_buf(),
                source,
            })?;
        Ok(Recorder { shared })
    }

    fn lock(&self) -> MutexGuard<'_, Option<BagWriter>> {
        // A panic while holding the lock leaves the writer usable: its state is updated only
        // after each successful write.
        self.shared.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Records `message` on `topic`, received now.
    pub fn record<M: RosMessage>(
        &self,
        topic: &str,
        offered_qos: &Qos,
        message: &M,
    ) -> Result<(), BagError> {
        self.record_at(topic, offered_qos, Time::now(), message)
    }

    /// Records `message` on `topic` with the given receive time.
    pub fn record_at<M: RosMessage>(
        &self,
        topic: &str,
        offered_qos: &Qos,
        time: Time,
        message: &M,
    ) -> Result<(), BagError> {
        let log_time = u64::try_from(time.to_nanos()).unwrap_or(0);
        self.lock()
            .as_mut()
            .ok_or(BagError::Finished)?
            .write(topic, offered_qos, log_time, message)
    }

    /// Records an already serialized message (CDR with encapsulation header), declaring the
    /// topic if needed; for replaying recorded bytes without decoding them.
    #[allow(clippy::too_many_arguments)]
    pub fn record_raw(
        &self,
        topic: &str,
        type_name: &str,
        definition: &str,
        type_hash: &str,
        offered_qos: &[Qos],
        log_time: u64,
        cdr: &[u8],
    ) -> Result<(), BagError> {
        let mut guard = self.lock();
        let writer = guard.as_mut().ok_or(BagError::Finished)?;
        writer.add_topic(topic, type_name, definition, type_hash, offered_qos)?;
        writer.write_raw(topic, log_time, log_time, cdr)
    }

    /// Closes the open chunk and pushes everything to the operating system now (it survives
    /// the process being killed).
    pub fn flush(&self) -> Result<(), BagError> {
        self.lock().as_mut().ok_or(BagError::Finished)?.flush()
    }

    /// [`Recorder::flush`], then `fsync`: everything recorded so far survives even a power
    /// cut. Called once a run's input is recorded, before its planning starts.
    pub fn sync(&self) -> Result<(), BagError> {
        self.lock().as_mut().ok_or(BagError::Finished)?.sync()
    }

    /// Finishes the bag (summary, footer, final metadata). Later records fail with
    /// [`BagError::Finished`].
    pub fn finish(&self) -> Result<BagSummary, BagError> {
        let writer = self.lock().take().ok_or(BagError::Finished)?;
        writer.finish()
    }
}

fn flush_loop(weak: Weak<Mutex<Option<BagWriter>>>, period: std::time::Duration) {
    loop {
        thread::sleep(period);
        let Some(shared) = weak.upgrade() else {
            return;
        };
        let mut guard = shared.lock().unwrap_or_else(|e| e.into_inner());
        let Some(writer) = guard.as_mut() else {
            return;
        };
        if let Err(e) = writer.flush_if_due() {
            tracing::error!("recording to {}: {e}", writer.dir().display());
        }
    }
}
