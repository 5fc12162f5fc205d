//! Reading ROS 2 MCAP recordings: [`Recording`] opens a file, [`Replay`] streams its scans, each with
//! the odometry pose interpolated to the scan stamp and the sensor mount from `/tf_static`.
//!
//! The file is read with plain `read`/`seek` (no mmap), one chunk at a time, so memory stays at a
//! few chunks plus the scans waiting for odometry. With a summary section (every finished MCAP) the
//! messages come in log-time order through the chunk index; without one (a truncated file, or one
//! written without index) the file is read front to back, in file order, which is log-time order for
//! recorders that write live (rosbag2, [`crate::write::RecordingWriter`]).
//!
//! A scan is released once odometry has reached its stamp (or a few scans later, or at the end of the
//! file), so the pose is interpolated, not guessed. Any fault ends the replay with one `Err` item
//! after every scan decoded before it.
//!
//! ```no_run
//! use croprow_io::read::{Recording, ReplayConfig};
//! let mut replay = Recording::open("run.mcap")?.replay(&ReplayConfig::default())?;
//! while let Some(frame) = replay.next_scan() {
//!     let frame = frame?;
//!     println!("{} s: {} points, pose {:?}", frame.stamp_s, frame.points.len(), frame.odom_pose);
//! }
//! # Ok::<(), croprow_io::read::RecordingError>(())
//! ```

use std::collections::{HashMap, VecDeque};
use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use croprow_core::{ConfigError, Mount, Point3, Pose2, Scan, Twist2, error::check_range};
use mcap::McapError;
use mcap::sans_io::indexed_reader::{IndexedReadEvent, IndexedReader, IndexedReaderOptions};
use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};
use mcap::sans_io::summary_reader::{SummaryReadEvent, SummaryReader};
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::cloud::{Layout, LayoutError};
use crate::msg::{self, CdrError, Odometry, PointCloud2, RosMessage, TfMessage};
use crate::odom::{History, PoseGap};
use crate::tf::{LookupError, TransformBuffer};

/// The MCAP magic that opens every file.
const MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";
/// Largest record (chunk or message) read, bytes: a corrupt length field must not allocate the
/// machine away. 256 MiB is far above a 128-ring LiDAR scan (~10 MB).
const MAX_RECORD_BYTES: usize = 256 << 20;
/// The static transform topic.
pub const TF_STATIC: &str = "/tf_static";

/// Something that stops a recording from being read. Every message names the file's problem in
/// words a user can act on.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum RecordingError {
    /// The file could not be opened or read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// The file has no bytes.
    #[error("{0} is empty (0 bytes), not an MCAP recording")]
    Empty(PathBuf),
    /// The file does not start with the MCAP magic.
    #[error("{0} is not an MCAP recording (bad magic bytes)")]
    NotMcap(PathBuf),
    /// The file ends in the middle of a record.
    #[error("{path} is truncated: it ends in the middle of a record ({detail})")]
    Truncated {
        /// The file.
        path: PathBuf,
        /// What the MCAP reader saw.
        detail: String,
    },
    /// The file's records cannot be parsed or decompressed.
    #[error("{path} is corrupt: {detail}")]
    Corrupt {
        /// The file.
        path: PathBuf,
        /// What the MCAP reader saw.
        detail: String,
    },
    /// A topic the replay needs is not in the file.
    #[error("topic `{topic}` is not in the recording; it has: {available}")]
    MissingTopic {
        /// The topic asked for.
        topic: String,
        /// The file's topics with their types.
        available: String,
    },
    /// A topic carries another type or encoding than expected.
    #[error("topic `{topic}` carries `{found}`, expected `{expected}` with cdr encoding")]
    SchemaMismatch {
        /// The topic.
        topic: String,
        /// Schema name and encoding found.
        found: String,
        /// The expected schema.
        expected: &'static str,
    },
    /// A message's bytes do not decode as its type.
    #[error("message on `{topic}` at log time {log_time_ns} ns does not decode: {source}")]
    Decode {
        /// The topic.
        topic: String,
        /// Its log time, ns.
        log_time_ns: u64,
        /// The CDR error.
        source: CdrError,
    },
    /// A point cloud's layout cannot be decoded.
    #[error("point cloud on `{topic}` at {stamp_s:.6} s: {source}")]
    Layout {
        /// The topic.
        topic: String,
        /// The cloud stamp, s.
        stamp_s: f64,
        /// What is wrong with the layout.
        source: LayoutError,
    },
    /// No `/tf_static` chain from the base frame to the cloud's frame, and no fallback mount.
    #[error(
        "missing transform for the sensor mount: {0}; give a fallback mount (config `mount`) or record /tf_static"
    )]
    MissingTransform(#[source] LookupError),
    /// `/tf_static` holds a mount no robot has.
    #[error("the /tf_static mount {frame} is implausible: {source}")]
    BadMount {
        /// `base -> sensor`.
        frame: String,
        /// The check that failed.
        source: ConfigError,
    },
    /// Odometry names another body frame than the replay expects.
    #[error(
        "odometry on `{topic}` is for child frame `{found}`, expected `{expected}` (set replay.base_frame)"
    )]
    FrameMismatch {
        /// The topic.
        topic: String,
        /// The child frame found.
        found: String,
        /// The base frame configured.
        expected: String,
    },
    /// Odometry stamps went back in time.
    #[error("odometry on `{topic}` goes backwards in time: {stamp_s:.6} s after {previous_s:.6} s")]
    OdometryBackwards {
        /// The topic.
        topic: String,
        /// The previous stamp, s.
        previous_s: f64,
        /// The offending stamp, s.
        stamp_s: f64,
    },
    /// The replay settings are invalid.
    #[error(transparent)]
    Config(#[from] ConfigError),
}

/// How a recording is replayed: topics, frames and interpolation limits. The dotted names are
/// `replay.<field>`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ReplayConfig {
    /// The `sensor_msgs/msg/PointCloud2` topic. Default `/velodyne_points`.
    pub cloud_topic: String,
    /// The `nav_msgs/msg/Odometry` topic giving `odom -> base_link`. Default `/odometry/filtered`.
    pub odom_topic: String,
    /// The robot body frame the mount and odometry refer to. Default `base_link` (REP-105).
    pub base_frame: String,
    /// Longest extrapolation of odometry past its first or last sample, s. Default 0.1 (five
    /// samples of a 50 Hz filter): a scan further out gets no pose ([`PoseGap`]).
    pub max_extrapolation_s: f64,
    /// Longest odometry gap interpolated across, s. Default 0.5.
    pub max_odom_gap_s: f64,
    /// Scans held while waiting for odometry to reach their stamp before they are released with
    /// extrapolation. Default 8 (0.8 s at 10 Hz).
    pub max_pending_scans: usize,
    /// Mount used when `/tf_static` has no `base_frame -> cloud frame` chain. Default none: the replay
    /// then fails with [`RecordingError::MissingTransform`].
    pub fallback_mount: Option<Mount>,
}

impl Default for ReplayConfig {
    fn default() -> Self {
        Self {
            cloud_topic: "/velodyne_points".into(),
            odom_topic: "/odometry/filtered".into(),
            base_frame: "base_link".into(),
            max_extrapolation_s: 0.1,
            max_odom_gap_s: 0.5,
            max_pending_scans: 8,
            fallback_mount: None,
        }
    }
}

impl ReplayConfig {
    /// Checks the settings.
    pub fn validate(&self) -> Result<(), ConfigError> {
        for (field, v) in [("replay.cloud_topic", &self.cloud_topic), ("replay.odom_topic", &self.odom_topic)]
        {
            if v.is_empty() {
                return Err(ConfigError::invalid(field, "must name a topic"));
            }
        }
        if self.base_frame.is_empty() {
            return Err(ConfigError::invalid("replay.base_frame", "must name a frame"));
        }
        check_range("replay.max_extrapolation_s", self.max_extrapolation_s, 0.0, 1.0)?;
        check_range("replay.max_odom_gap_s", self.max_odom_gap_s, 0.0, 10.0)?;
        check_range("replay.max_pending_scans", self.max_pending_scans as f64, 1.0, 1000.0)?;
        if let Some(m) = &self.fallback_mount {
            m.validate()?;
        }
        Ok(())
    }
}

/// One topic of a recording.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TopicInfo {
    /// Topic name.
    pub topic: String,
    /// Schema name, e.g. `sensor_msgs/msg/PointCloud2`.
    pub schema_name: String,
    /// Message encoding, `cdr` for ROS 2.
    pub encoding: String,
    /// Messages on the topic (from the statistics record), when known.
    pub message_count: Option<u64>,
}

/// Where a scan's mount came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MountSource {
    /// A `/tf_static` chain from the base frame to the cloud's frame.
    TfStatic,
    /// The caller's fallback mount.
    Fallback,
}

/// One scan of a replay, borrowed from the replay until the next call.
#[derive(Debug, Clone, Copy)]
pub struct ScanFrame<'a> {
    /// The cloud's header stamp, s.
    pub stamp_s: f64,
    /// The cloud's log time, ns.
    pub log_time_ns: u64,
    /// The cloud's frame id.
    pub frame_id: &'a str,
    /// Points in the sensor frame, m.
    pub points: &'a [Point3],
    /// `odom -> base_link` at the scan stamp, or why there is none.
    pub odom_pose: Result<Pose2, PoseGap>,
    /// Body twist at the scan stamp from the odometry poses around it (the recording's own twist
    /// fields are often zero or in another frame), for the detector's deskew; `None` without a pose.
    pub odom_twist: Option<Twist2>,
    /// `base_link -> frame_id`.
    pub mount: Mount,
    /// Where the mount came from.
    pub mount_source: MountSource,
}

impl ScanFrame<'_> {
    /// The scan as the detector takes it.
    pub fn scan(&self) -> Scan<'_> {
        Scan { stamp_s: self.stamp_s, points: self.points, twist: self.odom_twist, attitude: None }
    }
}

/// A channel as the replay needs it.
#[derive(Debug, Clone)]
struct Channel {
    topic: String,
    schema_name: String,
    encoding: String,
}

/// An MCAP recording opened for reading.
#[derive(Debug)]
pub struct Recording {
    path: PathBuf,
    file: BufReader<File>,
    summary: Option<mcap::Summary>,
}

impl Recording {
    /// Opens a recording and reads its summary section when it has one.
    pub fn open(path: impl AsRef<Path>) -> Result<Self, RecordingError> {
        let path = path.as_ref().to_path_buf();
        let io = |source| RecordingError::Io { path: path.clone(), source };
        let mut file = File::open(&path).map_err(io)?;
        let len = file.metadata().map_err(io)?.len();
        if len == 0 {
            return Err(RecordingError::Empty(path));
        }
        let mut magic = [0u8; 8];
        if len < 8 || file.read_exact(&mut magic).is_err() || &magic != MAGIC {
            return Err(RecordingError::NotMcap(path));
        }
        // A file without a readable summary (truncated while recording, or never finished) is still
        // read front to back: everything before the damage is usable.
        let summary = read_summary(&mut file, len).ok().flatten().filter(|s| !s.chunk_indexes.is_empty());
        file.seek(SeekFrom::Start(0)).map_err(io)?;
        Ok(Self { path, file: BufReader::with_capacity(1 << 16, file), summary })
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// True when the file has a summary with a chunk index (messages come in log-time order).
    pub fn is_indexed(&self) -> bool {
        self.summary.is_some()
    }

    /// The topics listed in the summary, sorted by name; `None` without a summary.
    pub fn topics(&self) -> Option<Vec<TopicInfo>> {
        let summary = self.summary.as_ref()?;
        let counts = summary.stats.as_ref().map(|s| &s.channel_message_counts);
        let mut topics: Vec<TopicInfo> = summary
            .channels
            .values()
            .map(|c| TopicInfo {
                topic: c.topic.clone(),
                schema_name: c.schema.as_ref().map(|s| s.name.clone()).unwrap_or_default(),
                encoding: c.message_encoding.clone(),
                message_count: counts.and_then(|m| m.get(&c.id).copied()),
            })
            .collect();
        topics.sort_by(|a, b| a.topic.cmp(&b.topic));
        Some(topics)
    }

    /// Starts streaming scans. With a summary, the topics and their types are checked first and
    /// `/tf_static` is collected before the first scan.
    pub fn replay(self, config: &ReplayConfig) -> Result<Replay, RecordingError> {
        config.validate()?;
        let mut state = State::new(self.path.clone(), config.clone());
        let source = match self.summary {
            Some(summary) => {
                let channels: HashMap<u16, Channel> = summary
                    .channels
                    .iter()
                    .map(|(id, c)| {
                        let schema = c.schema.as_ref();
                        (
                            *id,
                            Channel {
                                topic: c.topic.clone(),
                                schema_name: schema.map(|s| s.name.clone()).unwrap_or_default(),
                                encoding: c.message_encoding.clone(),
                            },
                        )
                    })
                    .collect();
                for (topic, expected) in [
                    (&config.cloud_topic, <PointCloud2<'_> as RosMessage>::TYPE_NAME),
                    (&config.odom_topic, Odometry::TYPE_NAME),
                ] {
                    let channel = channels
                        .values()
                        .find(|c| &c.topic == topic)
                        .ok_or_else(|| missing_topic(topic, channels.values()))?;
                    check_schema(channel, expected)?;
                }
                state.channels = channels.clone();
                let mut file = self.file;
                if channels.values().any(|c| c.topic == TF_STATIC) {
                    // Static transforms may be published at any time; read them all up front so the
                    // first scans already have their mount.
                    let opts = IndexedReaderOptions::new()
                        .with_record_length_limit(MAX_RECORD_BYTES)
                        .include_topics([TF_STATIC]);
                    let reader =
                        IndexedReader::new_with_options(&summary, opts).map_err(|e| state.mcap_error(e))?;
                    let mut source = Source::Indexed { reader, file, buf: Vec::new() };
                    while let Some(step) = source.step(&mut state, true) {
                        step?;
                    }
                    file = source.into_file();
                }
                let topics = [config.cloud_topic.clone(), config.odom_topic.clone()];
                let opts = IndexedReaderOptions::new()
                    .with_record_length_limit(MAX_RECORD_BYTES)
                    .include_topics(topics);
                let reader =
                    IndexedReader::new_with_options(&summary, opts).map_err(|e| state.mcap_error(e))?;
                Source::Indexed { reader, file, buf: Vec::new() }
            }
            None => Source::Linear {
                reader: LinearReader::new_with_options(
                    LinearReaderOptions::default()
                        .with_emit_chunks(true)
                        .with_validate_chunk_crcs(true)
                        .with_record_length_limit(MAX_RECORD_BYTES),
                ),
                file: self.file,
                schemas: HashMap::new(),
            },
        };
        Ok(Replay { source: Some(source), state, current: Vec::new() })
    }
}

fn missing_topic<'a>(topic: &str, channels: impl Iterator<Item = &'a Channel>) -> RecordingError {
    let mut list: Vec<String> = channels.map(|c| format!("{} ({})", c.topic, c.schema_name)).collect();
    list.sort();
    list.dedup();
    RecordingError::MissingTopic {
        topic: topic.to_owned(),
        available: if list.is_empty() { "no topics".to_owned() } else { list.join(", ") },
    }
}

fn check_schema(channel: &Channel, expected: &'static str) -> Result<(), RecordingError> {
    if channel.schema_name != expected || channel.encoding != "cdr" {
        return Err(RecordingError::SchemaMismatch {
            topic: channel.topic.clone(),
            found: format!("{} ({})", channel.schema_name, channel.encoding),
            expected,
        });
    }
    Ok(())
}

fn read_summary(file: &mut File, len: u64) -> Result<Option<mcap::Summary>, McapError> {
    let mut reader = SummaryReader::new_with_options(
        mcap::sans_io::summary_reader::SummaryReaderOptions::default()
            .with_file_size(len)
            .with_record_length_limit(MAX_RECORD_BYTES),
    );
    while let Some(event) = reader.next_event() {
        match event? {
            SummaryReadEvent::ReadRequest(n) => {
                let read = file.read(reader.insert(n))?;
                reader.notify_read(read);
            }
            SummaryReadEvent::SeekRequest(to) => {
                let pos = file.seek(to)?;
                reader.notify_seeked(pos);
            }
        }
    }
    Ok(reader.finish())
}

/// Where messages come from: the chunk index (log-time order) or a front-to-back read.
enum Source {
    Indexed { reader: IndexedReader, file: BufReader<File>, buf: Vec<u8> },
    Linear { reader: LinearReader, file: BufReader<File>, schemas: HashMap<u16, (String, String)> },
}

impl Source {
    fn into_file(self) -> BufReader<File> {
        match self {
            Source::Indexed { file, .. } | Source::Linear { file, .. } => file,
        }
    }

    /// Advances by one event; a message is handed to `state`. `None` at the end of the file.
    fn step(&mut self, state: &mut State, tf_only: bool) -> Option<Result<(), RecordingError>> {
        match self {
            Source::Indexed { reader, file, buf } => {
                let event = match reader.next_event()? {
                    Ok(e) => e,
                    Err(e) => return Some(Err(state.mcap_error(e))),
                };
                match event {
                    IndexedReadEvent::ReadChunkRequest { offset, length } => {
                        // The chunk index is read from the file too: a corrupt entry must not size a
                        // buffer (up to the record limit) past the file's end.
                        let file_len = file.get_ref().metadata().map_or(u64::MAX, |m| m.len());
                        if offset.checked_add(length as u64).is_none_or(|end| end > file_len) {
                            return Some(Err(RecordingError::Corrupt {
                                path: state.path.clone(),
                                detail: format!(
                                    "the chunk index points at {length} bytes at offset {offset}, past the end of the {file_len}-byte file"
                                ),
                            }));
                        }
                        buf.resize(length, 0);
                        let read = file.seek(SeekFrom::Start(offset)).and_then(|_| file.read_exact(buf));
                        if let Err(e) = read {
                            return Some(Err(state.mcap_error(McapError::Io(e))));
                        }
                        Some(reader.insert_chunk_record_data(offset, buf).map_err(|e| state.mcap_error(e)))
                    }
                    IndexedReadEvent::Message { header, data } => {
                        Some(state.handle(header.channel_id, header.log_time, data, tf_only))
                    }
                }
            }
            Source::Linear { reader, file, schemas } => {
                let event = match reader.next_event()? {
                    Ok(e) => e,
                    Err(e) => return Some(Err(state.mcap_error(e))),
                };
                match event {
                    LinearReadEvent::ReadRequest(n) => {
                        let read = match file.read(reader.insert(n)) {
                            Ok(read) => read,
                            Err(e) => return Some(Err(state.mcap_error(McapError::Io(e)))),
                        };
                        reader.notify_read(read);
                        Some(Ok(()))
                    }
                    LinearReadEvent::Record { data, opcode } => match mcap::parse_record(opcode, data) {
                        Err(e) => Some(Err(state.mcap_error(e))),
                        Ok(mcap::records::Record::Chunk { header, data: body }) => {
                            Some(read_chunk(&header, &body, data, schemas, state, tf_only))
                        }
                        Ok(record) => Some(read_record(record, schemas, state, tf_only)),
                    },
                }
            }
        }
    }
}

/// Hands one non-chunk record of a front-to-back read to `state`.
fn read_record(
    record: mcap::records::Record<'_>,
    schemas: &mut HashMap<u16, (String, String)>,
    state: &mut State,
    tf_only: bool,
) -> Result<(), RecordingError> {
    match record {
        mcap::records::Record::Schema { header, .. } => {
            schemas.insert(header.id, (header.name, header.encoding));
            Ok(())
        }
        mcap::records::Record::Channel(c) => {
            let (schema_name, _) = schemas.get(&c.schema_id).cloned().unwrap_or_default();
            state.add_channel(c.id, Channel { topic: c.topic, schema_name, encoding: c.message_encoding })
        }
        mcap::records::Record::Message { header, data } => {
            state.handle(header.channel_id, header.log_time, &data, tf_only)
        }
        _ => Ok(()),
    }
}

/// Reads the records of one chunk of a front-to-back read.
///
/// The outer reader hands over whole chunks (`record` is the chunk record's body, `body` its
/// payload) and a second linear reader, fed only this chunk, opens it with the same record-length
/// limit. The detour exists because mcap 0.26 trusts the length of a record inside an uncompressed
/// chunk: one longer than what is left of its chunk underflows a counter (a panic with overflow
/// checks, a read past the chunk without). Such chunks are refused here before they are parsed.
fn read_chunk(
    header: &mcap::records::ChunkHeader,
    body: &[u8],
    record: &[u8],
    schemas: &mut HashMap<u16, (String, String)>,
    state: &mut State,
    tf_only: bool,
) -> Result<(), RecordingError> {
    let corrupt = |detail| RecordingError::Corrupt { path: state.path.clone(), detail };
    if header.compression.is_empty() {
        if header.uncompressed_size != body.len() as u64 {
            return Err(corrupt(format!(
                "an uncompressed chunk of {} bytes claims {}",
                body.len(),
                header.uncompressed_size
            )));
        }
        check_chunk_records(body).map_err(corrupt)?;
    }
    let mut input = Vec::with_capacity(9 + record.len());
    input.push(mcap::records::op::CHUNK);
    input.extend_from_slice(&(record.len() as u64).to_le_bytes());
    input.extend_from_slice(record);
    let mut rest = input.as_slice();
    let mut reader = LinearReader::new_with_options(
        LinearReaderOptions::default()
            .with_skip_start_magic(true)
            .with_skip_end_magic(true)
            .with_validate_chunk_crcs(true)
            .with_record_length_limit(MAX_RECORD_BYTES),
    );
    while let Some(event) = reader.next_event() {
        match event.map_err(|e| state.mcap_error(e))? {
            LinearReadEvent::ReadRequest(n) => {
                let k = n.min(rest.len());
                reader.insert(k).copy_from_slice(&rest[..k]);
                reader.notify_read(k);
                rest = &rest[k..];
            }
            LinearReadEvent::Record { data, opcode } => {
                let inner = mcap::parse_record(opcode, data).map_err(|e| state.mcap_error(e))?;
                read_record(inner, schemas, state, tf_only)?;
            }
        }
    }
    Ok(())
}

/// Checks that every record of an uncompressed chunk (`opcode u8, length u64 LE, body`) ends inside it.
fn check_chunk_records(mut data: &[u8]) -> Result<(), String> {
    let mut offset = 0usize;
    while !data.is_empty() {
        let Some((&[opcode, l0, l1, l2, l3, l4, l5, l6, l7], rest)) = data.split_first_chunk::<9>() else {
            return Err(format!("a record header at chunk offset {offset} is cut by the end of its chunk"));
        };
        let len = u64::from_le_bytes([l0, l1, l2, l3, l4, l5, l6, l7]);
        let body = usize::try_from(len).ok().filter(|&n| n <= rest.len()).ok_or_else(|| {
            format!(
                "record 0x{opcode:02x} at chunk offset {offset} claims {len} bytes, the chunk has {} left",
                rest.len()
            )
        })?;
        data = &rest[body..];
        offset += 9 + body;
    }
    Ok(())
}

/// A scan waiting for odometry to reach its stamp.
struct Pending {
    stamp_s: f64,
    log_time_ns: u64,
    frame_id: String,
    points: Vec<Point3>,
}

/// Everything the replay knows so far.
struct State {
    path: PathBuf,
    config: ReplayConfig,
    channels: HashMap<u16, Channel>,
    tf: TransformBuffer,
    odom: History,
    pending: VecDeque<Pending>,
    /// Point buffers of released scans, reused for the next ones.
    pool: Vec<Vec<Point3>>,
    clouds_seen: usize,
    /// A fault met while scans were still waiting; reported after them.
    error: Option<RecordingError>,
    /// The replay has ended (its fault, if any, was reported).
    finished: bool,
    /// Frame id of the scan last released.
    current_frame: String,
}

impl State {
    fn new(path: PathBuf, config: ReplayConfig) -> Self {
        Self {
            path,
            odom: History::new(config.max_extrapolation_s, config.max_odom_gap_s),
            config,
            channels: HashMap::new(),
            tf: TransformBuffer::new(),
            pending: VecDeque::new(),
            pool: Vec::new(),
            clouds_seen: 0,
            error: None,
            finished: false,
            current_frame: String::new(),
        }
    }

    fn mcap_error(&self, e: McapError) -> RecordingError {
        let path = self.path.clone();
        match e {
            McapError::UnexpectedEof | McapError::UnexpectedEoc => {
                RecordingError::Truncated { path, detail: e.to_string() }
            }
            McapError::Io(ref io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
                RecordingError::Truncated { path, detail: e.to_string() }
            }
            McapError::BadMagic => RecordingError::NotMcap(path),
            other => RecordingError::Corrupt { path, detail: other.to_string() },
        }
    }

    fn add_channel(&mut self, id: u16, channel: Channel) -> Result<(), RecordingError> {
        if channel.topic == self.config.cloud_topic {
            check_schema(&channel, <PointCloud2<'_> as RosMessage>::TYPE_NAME)?;
        } else if channel.topic == self.config.odom_topic {
            check_schema(&channel, Odometry::TYPE_NAME)?;
        }
        self.channels.insert(id, channel);
        Ok(())
    }

    fn decode<'d, T: serde::Deserialize<'d>>(
        &self,
        topic: &str,
        log_time_ns: u64,
        data: &'d [u8],
    ) -> Result<T, RecordingError> {
        msg::decode(data).map_err(|source| RecordingError::Decode {
            topic: topic.to_owned(),
            log_time_ns,
            source,
        })
    }

    fn handle(
        &mut self,
        channel_id: u16,
        log_time_ns: u64,
        data: &[u8],
        tf_only: bool,
    ) -> Result<(), RecordingError> {
        let Some(channel) = self.channels.get(&channel_id) else {
            return Err(RecordingError::Corrupt {
                path: self.path.clone(),
                detail: format!("message at {log_time_ns} ns on unknown channel {channel_id}"),
            });
        };
        let topic = channel.topic.clone();
        if topic == TF_STATIC {
            if channel.schema_name == TfMessage::TYPE_NAME {
                let tf: TfMessage = self.decode(&topic, log_time_ns, data)?;
                for t in &tf.transforms {
                    self.tf.insert(t);
                }
            }
        } else if tf_only {
        } else if topic == self.config.cloud_topic {
            let cloud: PointCloud2<'_> = self.decode(&topic, log_time_ns, data)?;
            let stamp_s = cloud.header.stamp.as_seconds();
            let layout_error = |source| RecordingError::Layout { topic: topic.clone(), stamp_s, source };
            let layout = Layout::of(&cloud).map_err(layout_error)?;
            let mut points = self.pool.pop().unwrap_or_default();
            layout.decode(&cloud.data, &mut points).map_err(layout_error)?;
            self.clouds_seen += 1;
            self.pending.push_back(Pending { stamp_s, log_time_ns, frame_id: cloud.header.frame_id, points });
        } else if topic == self.config.odom_topic {
            let odom: Odometry = self.decode(&topic, log_time_ns, data)?;
            if !odom.child_frame_id.is_empty() && odom.child_frame_id != self.config.base_frame {
                return Err(RecordingError::FrameMismatch {
                    topic,
                    found: odom.child_frame_id,
                    expected: self.config.base_frame.clone(),
                });
            }
            let p = odom.pose.pose;
            let pose = Pose2::new(p.position.x, p.position.y, p.orientation.yaw());
            let stamp_s = odom.header.stamp.as_seconds();
            if pose.is_finite() {
                self.odom.push(stamp_s, pose).map_err(|b| RecordingError::OdometryBackwards {
                    topic,
                    previous_s: b.previous_s,
                    stamp_s: b.stamp_s,
                })?;
            }
        }
        Ok(())
    }

    /// True when the oldest waiting scan can be released.
    fn front_ready(&self, at_end: bool) -> bool {
        let Some(front) = self.pending.front() else { return false };
        at_end
            || self.pending.len() > self.config.max_pending_scans
            || self.odom.latest_s().is_some_and(|t| t >= front.stamp_s)
    }

    fn mount_for(&self, frame_id: &str) -> Result<(Mount, MountSource), RecordingError> {
        match self.tf.lookup(&self.config.base_frame, frame_id) {
            Ok(iso) => {
                let t = iso.translation.vector;
                let q = iso.rotation.quaternion().coords; // (i, j, k, w)
                let mount = Mount::from_translation_quaternion([t.x, t.y, t.z], [q.x, q.y, q.z, q.w])
                    .map_err(|source| RecordingError::BadMount {
                        frame: format!("{} -> {frame_id}", self.config.base_frame),
                        source,
                    })?;
                Ok((mount, MountSource::TfStatic))
            }
            // A chain that exists but overflows is a broken mount, not a missing one: no fallback.
            Err(LookupError::NonFinite { .. }) => Err(RecordingError::BadMount {
                frame: format!("{} -> {frame_id}", self.config.base_frame),
                source: ConfigError::invalid(
                    "mount",
                    "the /tf_static chain composes to a non-finite transform",
                ),
            }),
            Err(e) => match self.config.fallback_mount {
                Some(m) => Ok((m, MountSource::Fallback)),
                None => Err(RecordingError::MissingTransform(e)),
            },
        }
    }
}

/// A stream of scans from a recording; see the module docs. Call [`Replay::next_scan`] until it
/// returns `None`.
pub struct Replay {
    source: Option<Source>,
    state: State,
    current: Vec<Point3>,
}

impl std::fmt::Debug for Replay {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Replay")
            .field("path", &self.state.path)
            .field("pending", &self.state.pending.len())
            .finish()
    }
}

impl Replay {
    /// The static transforms collected so far.
    pub fn transforms(&self) -> &TransformBuffer {
        &self.state.tf
    }

    /// The next scan, or the fault that ends the replay (after which it returns `None`). The frame
    /// borrows the replay's buffers: its points are valid until the next call, which reuses them.
    pub fn next_scan(&mut self) -> Option<Result<ScanFrame<'_>, RecordingError>> {
        if self.state.finished {
            return None;
        }
        let mut fault = None;
        while let Some(source) = self.source.as_mut() {
            if self.state.front_ready(false) {
                break;
            }
            match source.step(&mut self.state, false) {
                Some(Ok(())) => {}
                Some(Err(e)) => {
                    fault = Some(e);
                    self.source = None;
                }
                None => self.source = None,
            }
        }
        let at_end = self.source.is_none();
        if !self.state.front_ready(at_end) {
            // Nothing left to release: report the fault, or a cloud topic that never appeared.
            self.state.finished = true;
            if let Some(e) = fault.or_else(|| self.state.error.take()) {
                return Some(Err(e));
            }
            // Without a summary the topics are only known at the end of the file.
            let config = &self.state.config;
            let has_odom = self.state.channels.values().any(|c| c.topic == config.odom_topic);
            if self.state.clouds_seen == 0 {
                return Some(Err(missing_topic(&config.cloud_topic, self.state.channels.values())));
            }
            if !has_odom {
                return Some(Err(missing_topic(&config.odom_topic, self.state.channels.values())));
            }
            return None;
        }
        // Scans decoded before a fault are still released; the fault follows them.
        if fault.is_some() {
            self.state.error = fault;
        }
        let front = self.state.pending.pop_front()?;
        let previous = std::mem::replace(&mut self.current, front.points);
        self.state.pool.push(previous);
        let odom_pose = self.state.odom.pose_at(front.stamp_s);
        let odom_twist = self.state.odom.twist_at(front.stamp_s);
        self.state.odom.forget_before(front.stamp_s - self.state.config.max_extrapolation_s);
        let (mount, mount_source) = match self.state.mount_for(&front.frame_id) {
            Ok(m) => m,
            Err(e) => {
                self.source = None;
                self.state.pending.clear();
                self.state.finished = true;
                return Some(Err(e));
            }
        };
        self.state.current_frame = front.frame_id;
        Some(Ok(ScanFrame {
            stamp_s: front.stamp_s,
            log_time_ns: front.log_time_ns,
            frame_id: &self.state.current_frame,
            points: &self.current,
            odom_pose,
            odom_twist,
            mount,
            mount_source,
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(opcode: u8, body: &[u8]) -> Vec<u8> {
        let mut r = vec![opcode];
        r.extend_from_slice(&(body.len() as u64).to_le_bytes());
        r.extend_from_slice(body);
        r
    }

    #[test]
    fn chunk_records_must_end_inside_their_chunk() {
        let mut chunk = record(0x05, &[1, 2, 3]);
        chunk.extend(record(0x05, &[]));
        assert_eq!(check_chunk_records(&chunk), Ok(()));
        assert_eq!(check_chunk_records(&[]), Ok(()));
        let cut = &chunk[..chunk.len() - 1];
        assert!(check_chunk_records(cut).unwrap_err().contains("cut by the end"));
        // The second record (at offset 12) claims one byte more than the chunk holds.
        chunk[13] = 1;
        assert!(check_chunk_records(&chunk).unwrap_err().contains("claims 1 bytes, the chunk has 0 left"));
        // A length of 2^63 is refused, not added to an offset.
        chunk[20] = 0x80;
        assert!(check_chunk_records(&chunk).is_err());
    }
}
