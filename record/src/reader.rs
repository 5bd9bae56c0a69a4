//! Reading recordings back: a streaming reader that needs no index (and so
//! reads a killed or truncated file up to its last complete set), an
//! indexed reader that seeks by time, `repair` (rewrite with indexes) and
//! `info`.
//!
//! A set is complete when its `/rig/telemetry` message has been read: the
//! writer puts it last in the set's chunk. A file that ends inside a chunk
//! or record ends the sets there; the reason is kept as the file's tail
//! ([`SetStream::tail`]), not reported as an error of the sets before it.

use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use mcap::records::{MessageHeader, Record};
use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};
use mcap::sans_io::summary_reader::{SummaryReadEvent, SummaryReader, SummaryReaderOptions};
use rigview_core::exposure::ExposureSetting;
use rigview_core::source::{CameraInfo, Frame, FrameMeta, FrameSet};

use crate::error::{RecordError, Result};
use crate::msgs::{self, FrameMetaMsg, SetTelemetryMsg};
use crate::writer::{END_METADATA, METADATA, RIG_ATTACHMENT, TELEMETRY_TOPIC};

mod indexed;
mod info;
mod repair;

pub use indexed::IndexedRecording;
pub use info::{info, RecordingInfo};
pub use repair::{repair, RepairReport};

/// What the recording says about itself.
#[derive(Clone, Debug, PartialEq)]
pub struct RecordingMeta {
    /// The cameras, in rig order.
    pub cameras: Vec<CameraInfo>,
    /// Added to the source's timestamps to make the log times.
    pub time_offset_ns: u64,
    /// The version of rigview that wrote it.
    pub version: String,
    /// The source, in words.
    pub source: String,
    /// The rig (rig YAML), if the recording has one.
    pub rig_yaml: Option<String>,
}

/// The end record: how the recording ended (absent in a killed file).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RecordingEnd {
    /// Sets written.
    pub sets: u64,
    /// Sets dropped.
    pub dropped: u64,
    /// Why it ended.
    pub stopped: String,
}

/// One recorded set.
#[derive(Clone, Debug)]
pub struct RecordedSet {
    /// The set as the source gave it (timestamps in the source's clock).
    pub set: FrameSet,
    /// Its log time (Unix ns).
    pub log_time: u64,
    /// Its telemetry as recorded.
    pub telemetry: SetTelemetryMsg,
}

fn parse_meta(file: &Path, m: &BTreeMap<String, String>) -> Result<RecordingMeta> {
    let get = |k: &str| {
        m.get(k).cloned().ok_or_else(|| {
            RecordError::format(
                file,
                format!("the metadata record \"{METADATA}\" has no \"{k}\""),
            )
        })
    };
    let cameras: Vec<CameraInfo> = serde_norway::from_str(&get("cameras_yaml")?)
        .map_err(|e| RecordError::format(file, format!("the metadata's \"cameras_yaml\": {e}")))?;
    let offset = get("time_offset_ns")?;
    let time_offset_ns = offset.parse().map_err(|_| {
        RecordError::format(
            file,
            format!("the metadata's \"time_offset_ns\" is \"{offset}\", expected an integer"),
        )
    })?;
    Ok(RecordingMeta {
        cameras,
        time_offset_ns,
        version: get("version")?,
        source: m.get("source").cloned().unwrap_or_default(),
        rig_yaml: None,
    })
}

fn parse_end(m: &BTreeMap<String, String>) -> RecordingEnd {
    let num = |k: &str| m.get(k).and_then(|v| v.parse().ok()).unwrap_or(0);
    RecordingEnd {
        sets: num("sets"),
        dropped: num("dropped_sets"),
        stopped: m.get("stopped").cloned().unwrap_or_default(),
    }
}

/// What a topic is to the assembler.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Topic {
    Image(usize),
    Meta(usize),
    Telemetry,
    Other,
}

/// Puts sets together from their messages.
#[derive(Debug)]
struct Assembler {
    file: PathBuf,
    meta: Option<RecordingMeta>,
    names: HashMap<u16, String>,
    topics: HashMap<u16, Topic>,
    pending: Vec<Option<FrameMetaMsg>>,
    frames: Vec<Option<Frame>>,
    trigger: Option<u64>,
}

impl Assembler {
    fn new(file: &Path) -> Self {
        Self {
            file: file.to_owned(),
            meta: None,
            names: HashMap::new(),
            topics: HashMap::new(),
            pending: Vec::new(),
            frames: Vec::new(),
            trigger: None,
        }
    }

    fn set_meta(&mut self, meta: RecordingMeta) {
        let n = meta.cameras.len();
        self.pending = vec![None; n];
        self.frames = vec![None; n];
        self.meta = Some(meta);
    }

    fn channel(&mut self, id: u16, topic: &str) {
        self.names.insert(id, topic.to_owned());
        self.topics.remove(&id);
    }

    /// What channel `id` is (resolved once the cameras are known).
    fn topic(&mut self, id: u16) -> Topic {
        if let Some(t) = self.topics.get(&id) {
            return *t;
        }
        let (Some(meta), Some(topic)) = (&self.meta, self.names.get(&id)) else {
            return Topic::Other;
        };
        let t = if topic == TELEMETRY_TOPIC {
            Topic::Telemetry
        } else {
            let mut parts = topic.strip_prefix("/rig/").unwrap_or("").rsplitn(2, '/');
            let (stream, camera) = (parts.next(), parts.next());
            let index = camera.and_then(|c| meta.cameras.iter().position(|k| k.name == c));
            match (stream, index) {
                (Some("image_raw"), Some(i)) => Topic::Image(i),
                (Some("frame_meta"), Some(i)) => Topic::Meta(i),
                _ => Topic::Other,
            }
        };
        self.topics.insert(id, t);
        t
    }

    fn bad(&self, what: String) -> RecordError {
        RecordError::format(&self.file, what)
    }

    fn message(&mut self, channel: u16, log_time: u64, data: &[u8]) -> Result<Option<RecordedSet>> {
        let Some(meta) = &self.meta else {
            return Err(self.bad(format!(
                "a message comes before the metadata record \"{METADATA}\": not a rigview recording"
            )));
        };
        let offset = meta.time_offset_ns;
        match self.topic(channel) {
            Topic::Other => Ok(None),
            Topic::Meta(c) => {
                let m = msgs::decode_frame_meta(data)
                    .map_err(|e| self.bad(format!("frame_meta at log time {log_time}: {e}")))?;
                if self.trigger != Some(m.trigger) {
                    self.start(m.trigger);
                }
                self.pending[c] = Some(m);
                Ok(None)
            }
            Topic::Image(c) => {
                let Some(m) = self.pending[c].take() else {
                    return Err(self.bad(format!(
                        "an image of camera {c} at log time {log_time} without its frame_meta"
                    )));
                };
                let img = msgs::decode_image(data)
                    .map_err(|e| self.bad(format!("image_raw at log time {log_time}: {e}")))?;
                let format = msgs::pixel_format(&m.pixel_format).ok_or_else(|| {
                    self.bad(format!(
                        "frame_meta at log time {log_time}: unknown pixel format \"{}\"",
                        m.pixel_format
                    ))
                })?;
                let frame_meta = FrameMeta {
                    camera: c,
                    format,
                    width: img.width as usize,
                    height: img.height as usize,
                    taken: ExposureSetting {
                        shutter_us: m.exposure_us,
                        gain_db: m.gain_db,
                    },
                    timestamp_ns: m.camera_time_ns,
                    frame_id: m.camera_frame_id,
                    status: m.status,
                };
                let frame = Frame::new(frame_meta, Arc::from(img.data)).map_err(|e| {
                    self.bad(format!(
                        "image_raw of camera {c} at log time {log_time}: {e}"
                    ))
                })?;
                self.frames[c] = Some(frame);
                Ok(None)
            }
            Topic::Telemetry => {
                let t = msgs::decode_set_telemetry(data)
                    .map_err(|e| self.bad(format!("telemetry at log time {log_time}: {e}")))?;
                if self.trigger.is_some_and(|k| k != t.trigger) {
                    self.start(t.trigger);
                }
                let frames = std::mem::replace(&mut self.frames, vec![None; self.pending.len()]);
                self.pending.iter_mut().for_each(|p| *p = None);
                self.trigger = None;
                Ok(Some(RecordedSet {
                    set: FrameSet {
                        trigger: t.trigger,
                        timestamp_ns: log_time.saturating_sub(offset),
                        frames,
                    },
                    log_time,
                    telemetry: t,
                }))
            }
        }
    }

    /// Forgets a set that never closed.
    fn start(&mut self, trigger: u64) {
        self.frames.iter_mut().for_each(|f| *f = None);
        self.pending.iter_mut().for_each(|p| *p = None);
        self.trigger = Some(trigger);
    }
}

/// The largest record read (a set's chunk of four 4K 16-bit frames is a
/// tenth of it): a damaged length field is an error, not an allocation.
const RECORD_LIMIT: usize = 1 << 30;

/// Records of a file in order, without its index.
struct Pump<R> {
    file: PathBuf,
    src: R,
    reader: LinearReader,
    tail: Option<String>,
    done: bool,
}

impl<R: Read> Pump<R> {
    fn new(file: &Path, src: R, strict: bool) -> Self {
        let options = LinearReaderOptions::default()
            .with_record_length_limit(RECORD_LIMIT)
            .with_prevalidate_chunk_crcs(strict)
            .with_validate_data_section_crc(strict)
            .with_validate_summary_section_crc(strict);
        Self::with_options(file, src, options)
    }

    fn with_options(file: &Path, src: R, options: LinearReaderOptions) -> Self {
        Self {
            file: file.to_owned(),
            src,
            reader: LinearReader::new_with_options(options),
            tail: None,
            done: false,
        }
    }

    /// Calls `f` on the next record; `None` at the end (or at a damaged
    /// tail, kept in `self.tail`).
    fn next<T>(&mut self, f: impl FnOnce(Record<'_>) -> T) -> Option<Result<T>> {
        if self.done {
            return None;
        }
        loop {
            match self.reader.next_event() {
                None => {
                    self.done = true;
                    return None;
                }
                Some(Err(e)) => {
                    self.done = true;
                    self.tail = Some(e.to_string());
                    return None;
                }
                Some(Ok(LinearReadEvent::ReadRequest(n))) => {
                    let buf = self.reader.insert(n);
                    match read_some(&mut self.src, buf) {
                        Ok(k) => self.reader.notify_read(k),
                        Err(e) => {
                            self.done = true;
                            return Some(Err(RecordError::io(&self.file, e)));
                        }
                    }
                }
                Some(Ok(LinearReadEvent::Record { opcode, data })) => {
                    return match mcap::parse_record(opcode, data) {
                        Ok(r) => Some(Ok(f(r))),
                        Err(e) => {
                            self.done = true;
                            self.tail = Some(e.to_string());
                            None
                        }
                    };
                }
            }
        }
    }
}

fn read_some(src: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    loop {
        match src.read(buf) {
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            r => return r,
        }
    }
}

/// Reads the sets of a recording from start to end without its index (see
/// the module documentation).
pub struct SetStream<R> {
    pump: Pump<R>,
    asm: Assembler,
    end: Option<RecordingEnd>,
}

impl<R> std::fmt::Debug for SetStream<R> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SetStream")
            .field("file", &self.pump.file)
            .field("tail", &self.pump.tail)
            .finish_non_exhaustive()
    }
}

impl SetStream<BufReader<File>> {
    /// Opens `file`; CRCs are checked if `strict`.
    pub fn open(file: &Path, strict: bool) -> Result<Self> {
        let f = File::open(file).map_err(|e| RecordError::io(file, e))?;
        Self::new(file, BufReader::with_capacity(1 << 20, f), strict)
    }
}

/// One record as the set reader sees it.
enum Seen {
    Channel(u16, String),
    Message(MessageHeader, Vec<u8>),
    Meta(String, BTreeMap<String, String>),
    Rig(Vec<u8>),
    Data,
    Other,
}

fn seen(r: Record<'_>, copy_messages: bool) -> Seen {
    match r {
        Record::Channel(c) => Seen::Channel(c.id, c.topic),
        Record::Message { header, data } if copy_messages => {
            Seen::Message(header, data.into_owned())
        }
        Record::Message { .. } | Record::Chunk { .. } => Seen::Data,
        Record::Metadata(m) => Seen::Meta(m.name, m.metadata),
        Record::Attachment { header, data, .. } if header.name == RIG_ATTACHMENT => {
            Seen::Rig(data.into_owned())
        }
        _ => Seen::Other,
    }
}

impl<R: Read> SetStream<R> {
    /// A reader of `src`, named `file` in errors; reads up to the
    /// recording's metadata (an error if there is none before the first
    /// message).
    pub fn new(file: &Path, src: R, strict: bool) -> Result<Self> {
        let mut s = Self {
            pump: Pump::new(file, src, strict),
            asm: Assembler::new(file),
            end: None,
        };
        while s.asm.meta.is_none() {
            match s.pump.next(|r| seen(r, false)) {
                None => {
                    let tail = s.pump.tail.clone().map(|t| format!(" ({t})")).unwrap_or_default();
                    return Err(RecordError::format(
                        file,
                        format!("no metadata record \"{METADATA}\": not a rigview recording{tail}"),
                    ));
                }
                Some(r) => match r? {
                    Seen::Meta(name, m) if name == METADATA => {
                        s.asm.set_meta(parse_meta(file, &m)?);
                    }
                    Seen::Channel(id, topic) => s.asm.channel(id, &topic),
                    Seen::Data => {
                        return Err(RecordError::format(
                            file,
                            format!("a message comes before the metadata record \"{METADATA}\": not a rigview recording"),
                        ))
                    }
                    _ => {}
                },
            }
        }
        Ok(s)
    }

    /// What the recording says about itself (the rig once its attachment
    /// has been read, which comes before the first set).
    pub fn meta(&self) -> Option<&RecordingMeta> {
        self.asm.meta.as_ref()
    }

    /// Why the file ended before its proper end, once the sets are read
    /// (`None`: it ended properly, or has not been read to its end).
    pub fn tail(&self) -> Option<&str> {
        self.pump.tail.as_deref()
    }

    /// The end record, once read (absent in a killed file).
    pub fn end(&self) -> Option<&RecordingEnd> {
        self.end.as_ref()
    }

    /// Reads records up to the first set (so that the rig attachment, which
    /// precedes it, is known); the set is kept for [`Iterator::next`].
    fn step(&mut self) -> Option<Result<RecordedSet>> {
        loop {
            let r = match self.pump.next(|r| seen(r, true))? {
                Ok(r) => r,
                Err(e) => return Some(Err(e)),
            };
            match r {
                Seen::Channel(id, topic) => self.asm.channel(id, &topic),
                Seen::Message(h, data) => match self.asm.message(h.channel_id, h.log_time, &data) {
                    Ok(Some(set)) => return Some(Ok(set)),
                    Ok(None) => {}
                    Err(e) => return Some(Err(e)),
                },
                Seen::Meta(name, m) if name == END_METADATA => self.end = Some(parse_end(&m)),
                Seen::Rig(bytes) => {
                    if let Some(meta) = &mut self.asm.meta {
                        meta.rig_yaml = Some(String::from_utf8_lossy(&bytes).into_owned());
                    }
                }
                _ => {}
            }
        }
    }
}

impl<R: Read> Iterator for SetStream<R> {
    type Item = Result<RecordedSet>;
    fn next(&mut self) -> Option<Self::Item> {
        self.step()
    }
}
