//! `--connect`'s check that the other end is a Rerun viewer (issue 66): the SDK connects lazily
//! and drops what it cannot send, so a listener that never answered hung the run and one that
//! closed the connection lost the recording with exit 0. A Rerun viewer serves gRPC over
//! cleartext HTTP/2, whose server opens every connection with a SETTINGS frame (RFC 9113,
//! section 3.4): the check sends the client's preface and waits for that frame.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::Duration;

/// The client connection preface (RFC 9113, 3.4) and an empty SETTINGS frame.
const PREFACE: &[u8] = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n\x00\x00\x00\x04\x00\x00\x00\x00\x00";

/// HTTP/2's frame type for SETTINGS.
const SETTINGS: u8 = 0x4;

/// Whether `stream` answers as an HTTP/2 server within `timeout`; the reason if not.
pub fn speaks_grpc(mut stream: TcpStream, timeout: Duration) -> Result<(), String> {
    let io = |e: std::io::Error| match e.kind() {
        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut => {
            format!("it did not answer within {} s", timeout.as_secs_f64())
        }
        std::io::ErrorKind::UnexpectedEof => "it closed the connection".to_string(),
        _ => e.to_string(),
    };
    stream.set_read_timeout(Some(timeout)).map_err(io)?;
    stream.set_write_timeout(Some(timeout)).map_err(io)?;
    stream.write_all(PREFACE).map_err(io)?;
    // A frame header: 24-bit length, type, flags, stream id.
    let mut header = [0u8; 9];
    stream.read_exact(&mut header).map_err(io)?;
    if header[3] == SETTINGS && header[5..9] == [0, 0, 0, 0] {
        Ok(())
    } else {
        let shown: String = header.iter().map(|b| if b.is_ascii_graphic() { *b as char } else { '.' }).collect();
        Err(format!("it answered `{shown}`, not an HTTP/2 greeting"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::TcpListener;

    /// A listener on a free port that treats each connection with `serve`.
    fn listener(serve: fn(TcpStream)) -> TcpStream {
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = l.local_addr().unwrap();
        std::thread::spawn(move || {
            if let Ok((s, _)) = l.accept() {
                serve(s);
            }
        });
        TcpStream::connect(addr).unwrap()
    }

    #[test]
    fn silent_closing_and_foreign_listeners_are_told_apart_from_a_viewer() {
        let t = Duration::from_millis(300);
        let silent = speaks_grpc(listener(|_s| std::thread::sleep(Duration::from_secs(2))), t);
        assert!(silent.as_ref().is_err_and(|e| e.contains("did not answer")), "{silent:?}");
        let closing = speaks_grpc(listener(drop), t);
        assert!(closing.as_ref().is_err_and(|e| e.contains("closed") || e.contains("reset")), "{closing:?}");
        let web = speaks_grpc(
            listener(|mut s| {
                let _ = s.write_all(b"HTTP/1.1 400 Bad Request\r\n\r\n");
                std::thread::sleep(Duration::from_millis(500));
            }),
            t,
        );
        assert!(web.as_ref().is_err_and(|e| e.contains("HTTP/1.1")), "{web:?}");
        // An HTTP/2 server's first frame: SETTINGS on stream 0 (here with one setting).
        let h2 = speaks_grpc(
            listener(|mut s| {
                let _ = s.write_all(&[0, 0, 6, 4, 0, 0, 0, 0, 0, 0, 3, 0, 0, 0, 100]);
                std::thread::sleep(Duration::from_millis(500));
            }),
            t,
        );
        assert_eq!(h2, Ok(()));
    }
}
