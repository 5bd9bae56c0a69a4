//! `repair`: a recording rewritten with its indexes, from its complete
//! sets.

use super::*;

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
