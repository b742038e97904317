//! A recording's file once it has ended, however it ended: cut back to its last whole piece
//! (an MP4's last whole box, a TS's last whole packet), so a file the disk stopped mid-write
//! plays to its end without an error; and removed when it holds no frame at all, so a
//! recording that never got going leaves no empty file behind. `record` calls it.

use super::record::Container;
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

/// What was left of a recording's file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Left {
    /// Kept, with the bytes cut from its end (0: it ended whole).
    Kept { cut: u64 },
    /// It held no frame and was removed (or was never made).
    Removed,
}

/// Cuts `path` back to its last whole piece, or removes it when no frame is in it.
pub fn tidy(path: &Path, container: Container) -> std::io::Result<Left> {
    let mut file = match std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(path)
    {
        Ok(f) => f,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Left::Removed),
        Err(e) => return Err(e),
    };
    let len = file.metadata()?.len();
    let whole = match container {
        Container::Mp4 => mp4_whole(&mut file, len)?,
        Container::Ts => ts_whole(&mut file, len)?,
    };
    match whole {
        Some(end) => {
            if end < len {
                // Cutting frees space, so it works on a full disk.
                file.set_len(end)?;
            }
            Ok(Left::Kept { cut: len - end })
        }
        None => {
            drop(file);
            std::fs::remove_file(path)?;
            Ok(Left::Removed)
        }
    }
}

/// Where a fragmented MP4's frames end: after its last whole `mdat` box and the whole boxes
/// that follow it, but not after a `moof` whose `mdat` is missing. None when no `mdat` is whole.
fn mp4_whole(file: &mut std::fs::File, len: u64) -> std::io::Result<Option<u64>> {
    let mut at = 0u64;
    let mut end = None;
    while at + 8 <= len {
        let mut head = [0u8; 16];
        file.seek(SeekFrom::Start(at))?;
        let n = file.read(&mut head)?;
        let size = match u32::from_be_bytes([head[0], head[1], head[2], head[3]]) {
            0 => len - at,
            1 if n >= 16 => u64::from_be_bytes(head[8..16].try_into().unwrap_or_default()),
            1 => break,
            s => u64::from(s),
        };
        if size < 8 || size > len - at {
            break;
        }
        at += size;
        match &head[4..8] {
            b"mdat" => end = Some(at),
            b"moof" => {}
            _ if end.is_some() => end = Some(at),
            _ => {}
        }
    }
    Ok(end)
}

/// TS packets are 188 bytes, each opening with 0x47.
const PACKET: u64 = 188;

/// Where an MPEG-TS's whole packets end, when one of them opens a video PES (a frame).
fn ts_whole(file: &mut std::fs::File, len: u64) -> std::io::Result<Option<u64>> {
    let end = len - len % PACKET;
    file.seek(SeekFrom::Start(0))?;
    let mut packet = [0u8; PACKET as usize];
    for _ in 0..end / PACKET {
        file.read_exact(&mut packet)?;
        if opens_video(&packet) {
            return Ok(Some(end));
        }
    }
    Ok(None)
}

/// Whether a TS packet starts a PES of a video stream (stream id 0xE0..=0xEF).
fn opens_video(p: &[u8; PACKET as usize]) -> bool {
    let starts = p[0] == 0x47 && p[1] & 0x40 != 0;
    let payload = match (p[3] >> 4) & 3 {
        1 => 4,
        3 => 5 + usize::from(p[4]),
        _ => return false,
    };
    starts
        && p.get(payload..payload + 4)
            .is_some_and(|h| h[..3] == [0, 0, 1] && h[3] & 0xF0 == 0xE0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn boxed(kind: &[u8; 4], body: usize) -> Vec<u8> {
        let mut b = ((body + 8) as u32).to_be_bytes().to_vec();
        b.extend_from_slice(kind);
        b.resize(body + 8, 7);
        b
    }

    fn file(name: &str, bytes: &[u8]) -> std::path::PathBuf {
        let path = std::env::temp_dir().join(format!("digiview-{}-{name}", std::process::id()));
        std::fs::write(&path, bytes).unwrap();
        path
    }

    #[test]
    fn an_mp4_cut_mid_fragment_keeps_its_whole_fragments() {
        let mut bytes = [boxed(b"ftyp", 16), boxed(b"moov", 600)].concat();
        let first = [boxed(b"moof", 100), boxed(b"mdat", 5000)].concat();
        bytes.extend(&first);
        let whole = bytes.len() as u64;
        bytes.extend(boxed(b"moof", 100));
        bytes.extend(&boxed(b"mdat", 5000)[..1234]);
        let path = file("cut.mp4", &bytes);
        let cut = bytes.len() as u64 - whole;
        assert_eq!(tidy(&path, Container::Mp4).unwrap(), Left::Kept { cut });
        assert_eq!(std::fs::metadata(&path).unwrap().len(), whole);
        // A whole file is left as it is.
        assert_eq!(tidy(&path, Container::Mp4).unwrap(), Left::Kept { cut: 0 });
        std::fs::remove_file(path).unwrap();
    }

    #[test]
    fn a_recording_with_no_frame_is_removed() {
        let header = [boxed(b"ftyp", 16), boxed(b"moov", 600), boxed(b"moof", 90)].concat();
        for (name, bytes, container) in [
            ("empty.mp4", vec![], Container::Mp4),
            ("header.mp4", header, Container::Mp4),
            ("empty.ts", vec![0x47; 188 * 3], Container::Ts),
        ] {
            let path = file(name, &bytes);
            assert_eq!(tidy(&path, container).unwrap(), Left::Removed, "{name}");
            assert!(!path.exists(), "{name} left behind");
        }
    }

    #[test]
    fn a_ts_keeps_its_whole_packets_from_the_first_frame() {
        let mut video = [0u8; 188];
        video[..8].copy_from_slice(&[0x47, 0x41, 0x00, 0x10, 0, 0, 1, 0xE0]);
        let mut bytes = [[0x47u8; 188].to_vec(), video.to_vec(), video.to_vec()].concat();
        bytes.truncate(188 * 3 - 50);
        let path = file("cut.ts", &bytes);
        assert_eq!(tidy(&path, Container::Ts).unwrap(), Left::Kept { cut: 138 });
        assert_eq!(std::fs::metadata(&path).unwrap().len(), 188 * 2);
        std::fs::remove_file(path).unwrap();
    }
}
