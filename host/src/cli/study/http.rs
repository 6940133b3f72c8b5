//! A minimal HTTP/1.1 server for the participant's page, on 127.0.0.1 only: one
//! request per connection, GET and POST with a `Content-Length` body, nothing else.
//! The session's loop polls it between its dealings with the sleeve, so no thread
//! shares the session's state.

use std::io::{self, BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::time::Duration;

/// The largest request body accepted (an answer is a few hundred bytes).
const MAX_BODY: usize = 64 * 1024;

/// A request as the session needs it.
#[derive(Debug)]
pub struct Request {
    /// `GET` or `POST`.
    pub method: String,
    /// The path, without a query.
    pub path: String,
    /// The body.
    pub body: Vec<u8>,
    stream: TcpStream,
}

/// An answer to send back.
pub struct Response {
    /// The status code.
    pub status: u16,
    /// The MIME type.
    pub mime: &'static str,
    /// The body.
    pub body: Vec<u8>,
}

impl Response {
    /// 200 with `body`.
    pub fn ok(mime: &'static str, body: impl Into<Vec<u8>>) -> Response {
        Response {
            status: 200,
            mime,
            body: body.into(),
        }
    }

    /// An error status with a short text.
    pub fn error(status: u16, text: &str) -> Response {
        Response {
            status,
            mime: "text/plain; charset=utf-8",
            body: text.as_bytes().to_vec(),
        }
    }
}

impl Request {
    /// Sends `r` and closes the connection. A page that went away is no error.
    pub fn respond(mut self, r: Response) {
        let reason = match r.status {
            200 => "OK",
            400 => "Bad Request",
            404 => "Not Found",
            409 => "Conflict",
            _ => "Error",
        };
        let head = format!(
            "HTTP/1.1 {} {reason}\r\nContent-Type: {}\r\nContent-Length: {}\r\nCache-Control: no-store\r\nConnection: close\r\n\r\n",
            r.status,
            r.mime,
            r.body.len()
        );
        let _ = self.stream.write_all(head.as_bytes());
        let _ = self.stream.write_all(&r.body);
    }
}

/// The listening socket.
pub struct Server {
    listener: TcpListener,
}

impl Server {
    /// Listens on 127.0.0.1:`port` (0: any free port).
    pub fn bind(port: u16) -> io::Result<Server> {
        let listener = TcpListener::bind(("127.0.0.1", port))?;
        listener.set_nonblocking(true)?;
        Ok(Server { listener })
    }

    /// The page's address.
    pub fn url(&self) -> io::Result<String> {
        Ok(format!("http://{}/", self.listener.local_addr()?))
    }

    /// The next request if one is waiting; a connection that sends garbage is
    /// answered 400 and dropped.
    pub fn poll(&self) -> Option<Request> {
        loop {
            let (stream, _) = self.listener.accept().ok()?;
            match read_request(stream) {
                Ok(r) => return Some(r),
                Err(_) => continue,
            }
        }
    }
}

fn read_request(stream: TcpStream) -> io::Result<Request> {
    stream.set_nonblocking(false)?;
    stream.set_read_timeout(Some(Duration::from_secs(2)))?;
    let mut reader = BufReader::new(stream.try_clone()?);
    let mut line = String::new();
    reader.read_line(&mut line)?;
    let mut parts = line.split_whitespace();
    let (method, target) = match (parts.next(), parts.next()) {
        (Some(m), Some(t)) => (m.to_string(), t.to_string()),
        _ => return Err(io::ErrorKind::InvalidData.into()),
    };
    let mut length = 0usize;
    loop {
        let mut h = String::new();
        if reader.read_line(&mut h)? == 0 || h.trim().is_empty() {
            break;
        }
        if let Some((k, v)) = h.split_once(':') {
            if k.trim().eq_ignore_ascii_case("content-length") {
                length = v
                    .trim()
                    .parse()
                    .map_err(|_| io::Error::from(io::ErrorKind::InvalidData))?;
            }
        }
    }
    if length > MAX_BODY {
        return Err(io::ErrorKind::InvalidData.into());
    }
    let mut body = vec![0; length];
    reader.read_exact(&mut body)?;
    let path = target.split('?').next().unwrap_or("/").to_string();
    Ok(Request {
        method,
        path,
        body,
        stream,
    })
}
