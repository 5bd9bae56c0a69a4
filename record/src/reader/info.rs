//! `info`: what a recording holds, from its summary where it has one and
//! from a scan where it has none.

use super::*;

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
