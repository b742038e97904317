//! MAVLink FTP, read only, for the one file a camera offers: its camera definition, at
//! `mftp://cameraN.xml` in camera N's CAMERA_INFORMATION (one name each: MAVSDK downloads
//! every camera's into one folder at once). A ground station downloads it over the MAVLink
//! link itself, so it needs neither the HTTP server nor a route to it, and MAVSDK takes this
//! path without the deadlock its HTTP download falls into when several cameras share one
//! definition (docs/decisions.md, "The camera definition over MAVLink FTP"). Each request is
//! answered from its own fields alone: reading is idempotent, so a repeated request (the
//! answer was lost) gets the same answer, and there is no session to leak.

/// The URI camera `i`'s CAMERA_INFORMATION gives.
pub fn definition_uri(i: usize) -> String {
    format!("mftp://camera{i}.xml")
}

/// Bytes of file data one message carries.
const DATA: usize = 239;
/// The payload's fields (MAVLink FTP's header), by offset.
const SEQ: usize = 0;
const SESSION: usize = 2;
const OPCODE: usize = 3;
const SIZE: usize = 4;
const REQ_OPCODE: usize = 5;
const BURST_COMPLETE: usize = 6;
const OFFSET: usize = 8;
const BODY: usize = 12;

const TERMINATE_SESSION: u8 = 1;
const RESET_SESSIONS: u8 = 2;
const OPEN_FILE_RO: u8 = 4;
const READ_FILE: u8 = 5;
const BURST_READ_FILE: u8 = 15;
const ACK: u8 = 128;
const NAK: u8 = 129;

/// NAK's error codes.
const EOF: u8 = 6;
const UNKNOWN_COMMAND: u8 = 7;
const FILE_PROTECTED: u8 = 9;
const FILE_NOT_FOUND: u8 = 10;

pub type Payload = [u8; 251];

/// The answers to one request `req` to camera `i`, whose definition is `file`: one message,
/// or for a burst read every chunk from the offset asked to the end.
pub fn answer(req: &Payload, i: usize, file: &[u8]) -> Vec<Payload> {
    let offset = u32::from_le_bytes(req[OFFSET..BODY].try_into().unwrap_or_default()) as usize;
    match req[OPCODE] {
        TERMINATE_SESSION | RESET_SESSIONS => vec![reply(req, ACK, 0, &[], false)],
        OPEN_FILE_RO => {
            let size = (req[SIZE] as usize).min(DATA);
            let path = String::from_utf8_lossy(&req[BODY..BODY + size]);
            match names_the_definition(&path, i) {
                true => vec![reply(
                    req,
                    ACK,
                    0,
                    &(file.len() as u32).to_le_bytes(),
                    false,
                )],
                false => vec![nak(req, FILE_NOT_FOUND)],
            }
        }
        READ_FILE if offset >= file.len() => vec![nak(req, EOF)],
        READ_FILE => {
            // The size asked for, or a whole message's worth when it names none.
            let asked = match req[SIZE] as usize {
                0 => DATA,
                n => n.min(DATA),
            };
            let n = asked.min(file.len() - offset);
            vec![reply(req, ACK, offset, &file[offset..offset + n], false)]
        }
        BURST_READ_FILE if offset >= file.len() => vec![nak(req, EOF)],
        BURST_READ_FILE => (offset..file.len())
            .step_by(DATA)
            .map(|at| {
                let end = (at + DATA).min(file.len());
                reply(req, ACK, at, &file[at..end], end == file.len())
            })
            .collect(),
        // Writing, removing, listing: this server offers one file to read.
        6..=14 | 16..=17 => vec![nak(req, FILE_PROTECTED)],
        _ => vec![nak(req, UNKNOWN_COMMAND)],
    }
}

/// Whether a requested path is camera `i`'s definition: `cameraN.xml` (or `camera.xml`),
/// with or without a leading slash and QGroundControl's `[;comp=N]` prefix.
fn names_the_definition(path: &str, i: usize) -> bool {
    let path = path.trim_end_matches('\0');
    let path = match path.strip_prefix("[;comp=") {
        Some(rest) => rest.split_once(']').map_or("", |(_, p)| p),
        None => path,
    };
    let name = path.trim_start_matches('/');
    name == "camera.xml" || name == format!("camera{i}.xml")
}

fn reply(req: &Payload, opcode: u8, offset: usize, data: &[u8], last: bool) -> Payload {
    let mut p = [0u8; 251];
    let seq = u16::from_le_bytes([req[SEQ], req[SEQ + 1]]).wrapping_add(1);
    p[SEQ..SEQ + 2].copy_from_slice(&seq.to_le_bytes());
    p[SESSION] = req[SESSION];
    p[OPCODE] = opcode;
    p[SIZE] = data.len() as u8;
    p[REQ_OPCODE] = req[OPCODE];
    p[BURST_COMPLETE] = last as u8;
    p[OFFSET..BODY].copy_from_slice(&(offset as u32).to_le_bytes());
    p[BODY..BODY + data.len()].copy_from_slice(data);
    p
}

fn nak(req: &Payload, error: u8) -> Payload {
    reply(req, NAK, 0, &[error], false)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn request(opcode: u8, offset: u32, body: &[u8]) -> Payload {
        let mut p = [0u8; 251];
        p[SEQ..SEQ + 2].copy_from_slice(&7u16.to_le_bytes());
        p[OPCODE] = opcode;
        p[SIZE] = body.len() as u8;
        p[OFFSET..BODY].copy_from_slice(&offset.to_le_bytes());
        p[BODY..BODY + body.len()].copy_from_slice(body);
        p
    }

    #[test]
    fn the_definition_reads_back_whole_by_reads_and_by_a_burst() {
        let file: Vec<u8> = (0..1000u32).map(|i| (i * 7 % 251) as u8).collect();
        for path in ["camera2.xml", "/camera.xml", "[;comp=102]/camera2.xml"] {
            let open = answer(&request(OPEN_FILE_RO, 0, path.as_bytes()), 2, &file);
            assert_eq!(open[0][OPCODE], ACK, "{path}");
            assert_eq!(&open[0][BODY..BODY + 4], &1000u32.to_le_bytes());
            assert_eq!(u16::from_le_bytes([open[0][0], open[0][1]]), 8, "seq + 1");
        }
        let mut got = Vec::new();
        loop {
            let r = answer(&request(READ_FILE, got.len() as u32, &[]), 2, &file);
            if r[0][OPCODE] == NAK {
                assert_eq!(r[0][BODY], EOF);
                break;
            }
            got.extend_from_slice(&r[0][BODY..BODY + r[0][SIZE] as usize]);
        }
        assert_eq!(got, file);
        let burst = answer(&request(BURST_READ_FILE, 0, &[]), 2, &file);
        let joined: Vec<u8> = burst
            .iter()
            .flat_map(|p| p[BODY..BODY + p[SIZE] as usize].to_vec())
            .collect();
        assert_eq!(joined, file);
        assert_eq!(burst.iter().filter(|p| p[BURST_COMPLETE] == 1).count(), 1);
        assert_eq!(burst.last().unwrap()[BURST_COMPLETE], 1);
    }

    #[test]
    fn other_files_and_writes_are_refused() {
        let file = b"<mavlinkcamera/>";
        for (req, code) in [
            (request(OPEN_FILE_RO, 0, b"/etc/passwd"), FILE_NOT_FOUND),
            (request(OPEN_FILE_RO, 0, b"../camera.xml"), FILE_NOT_FOUND),
            (request(OPEN_FILE_RO, 0, b"camera3.xml"), FILE_NOT_FOUND),
            (request(6, 0, b"x"), FILE_PROTECTED),
            (request(200, 0, b""), UNKNOWN_COMMAND),
            (request(READ_FILE, u32::MAX, b""), EOF),
        ] {
            let r = answer(&req, 2, file);
            assert_eq!((r[0][OPCODE], r[0][BODY]), (NAK, code));
        }
    }
}
