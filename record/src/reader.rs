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

/// Reads a recording through its index: sets by number or time, without
/// reading from the start.
pub struct IndexedRecording {
    file: PathBuf,
    f: File,
    summary: mcap::Summary,
    meta: RecordingMeta,
    end: Option<RecordingEnd>,
    /// Per set (in log-time order), its log time.
    times: Vec<u64>,
    /// Per set, where its chunk record is (offset, length).
    chunks: Vec<(u64, u64)>,
    buf: Vec<u8>,
}

impl std::fmt::Debug for IndexedRecording {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("IndexedRecording")
            .field("file", &self.file)
            .field("sets", &self.times.len())
            .finish_non_exhaustive()
    }
}

fn read_record_at(file: &Path, f: &mut File, offset: u64, length: u64) -> Result<(u8, Vec<u8>)> {
    let io = |e| RecordError::io(file, e);
    f.seek(SeekFrom::Start(offset)).map_err(io)?;
    let mut head = [0u8; 9];
    f.read_exact(&mut head).map_err(io)?;
    let len = u64::from_le_bytes(head[1..9].try_into().unwrap_or([0; 8]));
    if len + 9 > length.max(9) && length != 0 {
        return Err(RecordError::format(
            file,
            format!("the record at byte {offset} is longer than its index says"),
        ));
    }
    if len > RECORD_LIMIT as u64 {
        return Err(RecordError::format(
            file,
            format!("the record at byte {offset} claims {len} bytes"),
        ));
    }
    let mut body = vec![0u8; usize::try_from(len).unwrap_or(0)];
    f.read_exact(&mut body).map_err(io)?;
    Ok((head[0], body))
}

impl IndexedRecording {
    /// Opens `file` by its summary; a file without one (killed, or cut
    /// short) is an error that says to repair it.
    pub fn open(file: &Path) -> Result<Self> {
        let mut f = File::open(file).map_err(|e| RecordError::io(file, e))?;
        let size = f.metadata().map_err(|e| RecordError::io(file, e))?.len();
        let mut reader = SummaryReader::new_with_options(
            SummaryReaderOptions::default()
                .with_file_size(size)
                .with_record_length_limit(RECORD_LIMIT),
        );
        while let Some(event) = reader.next_event() {
            match event.map_err(|e| RecordError::mcap(file, e))? {
                SummaryReadEvent::ReadRequest(n) => {
                    let k = read_some(&mut f, reader.insert(n))
                        .map_err(|e| RecordError::io(file, e))?;
                    reader.notify_read(k);
                }
                SummaryReadEvent::SeekRequest(to) => {
                    let pos = f.seek(to).map_err(|e| RecordError::io(file, e))?;
                    reader.notify_seeked(pos);
                }
            }
        }
        let summary = reader.finish().ok_or_else(|| {
            RecordError::format(
                file,
                "the file has no summary (it was not closed: killed, or the disk filled); \
                 `rigview recording repair` rewrites it with one",
            )
        })?;
        let mut meta = None;
        let mut end = None;
        for m in &summary.metadata_indexes {
            let (op, body) = read_record_at(file, &mut f, m.offset, m.length)?;
            if let Record::Metadata(rec) =
                mcap::parse_record(op, &body).map_err(|e| RecordError::mcap(file, e))?
            {
                if rec.name == METADATA {
                    meta = Some(parse_meta(file, &rec.metadata)?);
                } else if rec.name == END_METADATA {
                    end = Some(parse_end(&rec.metadata));
                }
            }
        }
        let mut meta = meta.ok_or_else(|| {
            RecordError::format(
                file,
                format!("no metadata record \"{METADATA}\": not a rigview recording"),
            )
        })?;
        for a in &summary.attachment_indexes {
            if a.name == RIG_ATTACHMENT {
                let (op, body) = read_record_at(file, &mut f, a.offset, a.length)?;
                if let Record::Attachment { data, .. } =
                    mcap::parse_record(op, &body).map_err(|e| RecordError::mcap(file, e))?
                {
                    meta.rig_yaml = Some(String::from_utf8_lossy(&data).into_owned());
                }
            }
        }
        let telemetry = summary
            .channels
            .values()
            .find(|c| c.topic == TELEMETRY_TOPIC)
            .map(|c| c.id);
        let mut sets: Vec<(u64, u64, u64)> = summary
            .chunk_indexes
            .iter()
            .filter(|c| telemetry.is_some_and(|t| c.message_index_offsets.contains_key(&t)))
            .map(|c| (c.message_start_time, c.chunk_start_offset, c.chunk_length))
            .collect();
        sets.sort_unstable();
        let times = sets.iter().map(|s| s.0).collect();
        let chunks = sets.iter().map(|s| (s.1, s.2)).collect();
        Ok(Self {
            file: file.to_owned(),
            f,
            summary,
            meta,
            end,
            times,
            chunks,
            buf: Vec::new(),
        })
    }

    /// What the recording says about itself.
    pub fn meta(&self) -> &RecordingMeta {
        &self.meta
    }

    /// The end record.
    pub fn end(&self) -> Option<&RecordingEnd> {
        self.end.as_ref()
    }

    /// The sets' log times, in order.
    pub fn times(&self) -> &[u64] {
        &self.times
    }

    /// Sets in the recording.
    pub fn len(&self) -> usize {
        self.times.len()
    }

    /// Whether it holds no set.
    pub fn is_empty(&self) -> bool {
        self.times.is_empty()
    }

    /// The number of the first set at or after `log_time` (`len()` if
    /// none).
    pub fn position(&self, log_time: u64) -> usize {
        self.times.partition_point(|&t| t < log_time)
    }

    /// Set number `k` (in log-time order). Its chunk is read on its own
    /// and its CRC checked before the set is given.
    pub fn set(&mut self, k: usize) -> Result<Option<RecordedSet>> {
        let Some(&(offset, length)) = self.chunks.get(k) else {
            return Ok(None);
        };
        let io = |e| RecordError::io(&self.file, e);
        if length > RECORD_LIMIT as u64 {
            return Err(RecordError::format(
                &self.file,
                format!("the chunk at byte {offset} claims {length} bytes"),
            ));
        }
        self.f.seek(SeekFrom::Start(offset)).map_err(io)?;
        self.buf.resize(usize::try_from(length).unwrap_or(0), 0);
        self.f.read_exact(&mut self.buf).map_err(io)?;
        let options = LinearReaderOptions::default()
            .with_skip_start_magic(true)
            .with_skip_end_magic(true)
            .with_record_length_limit(RECORD_LIMIT)
            .with_prevalidate_chunk_crcs(true);
        let mut pump = Pump::with_options(&self.file, &self.buf[..], options);
        let mut asm = Assembler::new(&self.file);
        asm.set_meta(self.meta.clone());
        for c in self.summary.channels.values() {
            asm.channel(c.id, &c.topic);
        }
        while let Some(r) = pump.next(|r| seen(r, true)) {
            if let Seen::Message(h, data) = r? {
                if let Some(set) = asm.message(h.channel_id, h.log_time, &data)? {
                    return Ok(Some(set));
                }
            }
        }
        let why = pump.tail.map(|t| format!(": {t}")).unwrap_or_default();
        Err(RecordError::format(
            &self.file,
            format!("the set in the chunk at byte {offset} is not whole{why}"),
        ))
    }

    /// Every set, in log-time order.
    pub fn sets(&mut self) -> impl Iterator<Item = Result<RecordedSet>> + '_ {
        (0..self.times.len()).filter_map(move |k| self.set(k).transpose())
    }
}

/// What `repair` did.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RepairReport {
    /// Complete sets copied.
    pub sets: u64,
    /// Why the input ended early (`None`: it ended properly).
    pub tail: Option<String>,
}

/// Rewrites `input` into `output` (a new file) with its summary and
/// indexes, keeping every complete set (as `mcap recover` does, plus rigview's metadata and
/// attachment). A set cut off at the end is left out.
pub fn repair(input: &Path, output: &Path) -> Result<RepairReport> {
    let f = File::open(input).map_err(|e| RecordError::io(input, e))?;
    let mut pump = Pump::new(input, BufReader::with_capacity(1 << 20, f), false);
    let out = File::options()
        .write(true)
        .create_new(true)
        .open(output)
        .map_err(|e| RecordError::io(output, e))?;
    let mut w = mcap::WriteOptions::new()
        .profile("ros2")
        .library(format!(
            "rigview-record {} (repair)",
            env!("CARGO_PKG_VERSION")
        ))
        .compression(None)
        .chunk_size(None)
        .create(BufWriter::with_capacity(1 << 22, out))
        .map_err(|e| RecordError::mcap(output, e))?;
    let e = |err| RecordError::mcap(output, err);
    enum Item {
        Schema(u16, String, String, Vec<u8>),
        Channel(u16, u16, String, String, BTreeMap<String, String>),
        Message(MessageHeader, Vec<u8>),
        Meta(mcap::records::Metadata),
        Attachment(mcap::records::AttachmentHeader, Vec<u8>),
        Other,
    }
    let mut schemas: HashMap<u16, u16> = HashMap::new();
    let mut channels: HashMap<u16, u16> = HashMap::new();
    let mut telemetry = None;
    let mut held: Vec<(MessageHeader, Vec<u8>)> = Vec::new();
    let mut sets = 0u64;
    while let Some(item) = pump.next(|r| match r {
        Record::Schema { header, data } => {
            Item::Schema(header.id, header.name, header.encoding, data.into_owned())
        }
        Record::Channel(c) => {
            Item::Channel(c.id, c.schema_id, c.topic, c.message_encoding, c.metadata)
        }
        Record::Message { header, data } => Item::Message(header, data.into_owned()),
        Record::Metadata(m) => Item::Meta(m),
        Record::Attachment { header, data, .. } => Item::Attachment(header, data.into_owned()),
        _ => Item::Other,
    }) {
        match item? {
            Item::Schema(id, name, encoding, data) => {
                let new = w.add_schema(&name, &encoding, &data).map_err(e)?;
                schemas.insert(id, new);
            }
            Item::Channel(id, schema, topic, encoding, metadata) => {
                let s = schemas.get(&schema).copied().unwrap_or(0);
                let new = w.add_channel(s, &topic, &encoding, &metadata).map_err(e)?;
                if topic == TELEMETRY_TOPIC {
                    telemetry = Some(id);
                }
                channels.insert(id, new);
            }
            Item::Message(header, data) => {
                let closes = Some(header.channel_id) == telemetry;
                held.push((header, data));
                if closes {
                    for (mut h, d) in held.drain(..) {
                        let Some(&c) = channels.get(&h.channel_id) else {
                            return Err(RecordError::format(
                                input,
                                format!(
                                    "a message on channel {} that was never declared",
                                    h.channel_id
                                ),
                            ));
                        };
                        h.channel_id = c;
                        w.write_to_known_channel(&h, &d).map_err(e)?;
                    }
                    w.flush().map_err(e)?;
                    sets += 1;
                }
            }
            Item::Meta(m) => w.write_metadata(&m).map_err(e)?,
            Item::Attachment(h, data) => w
                .attach(&mcap::Attachment {
                    log_time: h.log_time,
                    create_time: h.create_time,
                    name: h.name,
                    media_type: h.media_type,
                    data: data.into(),
                })
                .map_err(e)?,
            Item::Other => {}
        }
    }
    w.finish().map_err(e)?;
    Ok(RepairReport {
        sets,
        tail: pump.tail,
    })
}

/// What `info` tells about a recording.
#[derive(Clone, Debug, PartialEq)]
pub struct RecordingInfo {
    /// What the recording says about itself.
    pub meta: RecordingMeta,
    /// Complete sets.
    pub sets: u64,
    /// The first and last set's log times.
    pub span_ns: Option<(u64, u64)>,
    /// Per topic, its schema and messages (of complete sets and the rest).
    pub topics: BTreeMap<String, (String, u64)>,
    /// Sets the recorder dropped (the end record, or the last set's count).
    pub dropped: u64,
    /// The end record (absent: killed or cut short).
    pub end: Option<RecordingEnd>,
    /// Why the file ended early (`None`: it ended properly).
    pub tail: Option<String>,
}

impl RecordingInfo {
    /// Seconds from the first set to the last.
    pub fn duration_s(&self) -> f64 {
        self.span_ns
            .map_or(0.0, |(a, b)| b.saturating_sub(a) as f64 * 1e-9)
    }
}

/// What a recording holds: from its summary if it has one, else by reading
/// it from start to end (without decoding its images).
pub fn info(file: &Path) -> Result<RecordingInfo> {
    match IndexedRecording::open(file) {
        Ok(r) => Ok(r.info()),
        Err(_) => scan_info(file),
    }
}

impl IndexedRecording {
    /// What the summary says.
    pub fn info(&self) -> RecordingInfo {
        let counts = self
            .summary
            .stats
            .as_ref()
            .map(|s| s.channel_message_counts.clone())
            .unwrap_or_default();
        let topics = self
            .summary
            .channels
            .values()
            .map(|c| {
                let schema = c
                    .schema
                    .as_ref()
                    .map(|s| s.name.clone())
                    .unwrap_or_default();
                let n = counts.get(&c.id).copied().unwrap_or(0);
                (c.topic.clone(), (schema, n))
            })
            .collect();
        RecordingInfo {
            meta: self.meta.clone(),
            sets: self.times.len() as u64,
            span_ns: self
                .times
                .first()
                .zip(self.times.last())
                .map(|(a, b)| (*a, *b)),
            topics,
            dropped: self.end.as_ref().map_or(0, |e| e.dropped),
            end: self.end.clone(),
            tail: None,
        }
    }
}

/// [`info`] of a file without a summary.
fn scan_info(file: &Path) -> Result<RecordingInfo> {
    let f = File::open(file).map_err(|e| RecordError::io(file, e))?;
    let mut pump = Pump::new(file, BufReader::with_capacity(1 << 20, f), false);
    enum Item {
        Schema(u16, String),
        Channel(u16, u16, String),
        Message(u16, u64, Option<u64>),
        Meta(String, BTreeMap<String, String>),
        Rig(Vec<u8>),
        Other,
    }
    let mut schemas = HashMap::new();
    let mut channels: HashMap<u16, (String, u16)> = HashMap::new();
    let mut telemetry = None;
    let mut topics: BTreeMap<String, (String, u64)> = BTreeMap::new();
    let (mut meta, mut end, mut rig) = (None, None, None);
    let (mut sets, mut span, mut dropped) = (0u64, None::<(u64, u64)>, 0u64);
    while let Some(item) = pump.next(|r| match r {
        Record::Schema { header, .. } => Item::Schema(header.id, header.name),
        Record::Channel(c) => Item::Channel(c.id, c.schema_id, c.topic),
        Record::Message { header, data } => {
            let t = (Some(header.channel_id) == telemetry)
                .then(|| msgs::decode_set_telemetry(&data).ok())
                .flatten()
                .map(|t| t.dropped_by_recorder);
            Item::Message(header.channel_id, header.log_time, t)
        }
        Record::Metadata(m) => Item::Meta(m.name, m.metadata),
        Record::Attachment { header, data, .. } if header.name == RIG_ATTACHMENT => {
            Item::Rig(data.into_owned())
        }
        _ => Item::Other,
    }) {
        match item? {
            Item::Schema(id, name) => {
                schemas.insert(id, name);
            }
            Item::Channel(id, schema, topic) => {
                if topic == TELEMETRY_TOPIC {
                    telemetry = Some(id);
                }
                let name = schemas.get(&schema).cloned().unwrap_or_default();
                topics.entry(topic.clone()).or_insert((name, 0));
                channels.insert(id, (topic, schema));
            }
            Item::Message(channel, log_time, t) => {
                if let Some((topic, _)) = channels.get(&channel) {
                    if let Some(e) = topics.get_mut(topic) {
                        e.1 += 1;
                    }
                }
                if let Some(d) = t {
                    sets += 1;
                    dropped = d;
                    span = Some(span.map_or((log_time, log_time), |(a, b)| {
                        (a.min(log_time), b.max(log_time))
                    }));
                }
            }
            Item::Meta(name, m) if name == METADATA => meta = Some(parse_meta(file, &m)?),
            Item::Meta(name, m) if name == END_METADATA => end = Some(parse_end(&m)),
            Item::Rig(bytes) => rig = Some(String::from_utf8_lossy(&bytes).into_owned()),
            _ => {}
        }
    }
    let mut meta: RecordingMeta = meta.ok_or_else(|| {
        RecordError::format(
            file,
            format!("no metadata record \"{METADATA}\": not a rigview recording"),
        )
    })?;
    meta.rig_yaml = rig;
    if let Some(e) = &end {
        dropped = dropped.max(e.dropped);
    }
    Ok(RecordingInfo {
        meta,
        sets,
        span_ns: span,
        topics,
        dropped,
        end,
        tail: pump.tail,
    })
}
