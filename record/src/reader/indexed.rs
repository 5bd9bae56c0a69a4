//! The indexed reader: sets by number or by time, read through the file's
//! chunk index without reading from the start.

use super::*;

/// Reads a recording through its index: sets by number or time, without
/// reading from the start.
pub struct IndexedRecording {
    file: PathBuf,
    f: File,
    pub(super) summary: mcap::Summary,
    pub(super) meta: RecordingMeta,
    pub(super) end: Option<RecordingEnd>,
    /// Per set (in log-time order), its log time.
    pub(super) times: Vec<u64>,
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
