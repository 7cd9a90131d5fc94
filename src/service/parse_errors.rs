//! hyper's own answers to requests it cannot parse, given the service's JSON
//! error body.
//!
//! hyper answers a request line or head it cannot parse (a `<` in a path, a
//! head over the accept loop's `HYPER_MAX_HEAD_BYTES`) itself, before any
//! handler or middleware sees the request, with a bare status line: `400`
//! (or `431`), `connection: close`, `content-length: 0`, and no way to
//! change it. Every other answer of the service has a JSON body naming what
//! was wrong, so clients can rely on one. [`JsonParseErrors`] wraps the
//! connection and swaps such a bare 4xx head, as hyper writes it, for the
//! same status with the JSON error body. Nothing the service's own handlers
//! write can match: their 4xx answers always carry a `content-type`.

use std::io::{self, IoSlice};
use std::pin::Pin;
use std::task::{Context, Poll, ready};

use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};

/// A connection whose bare 4xx answers from hyper get a JSON body.
pub struct JsonParseErrors<S> {
    inner: S,
    /// The answer that replaced hyper's, and how much of it is written.
    pending: Vec<u8>,
    written: usize,
}

impl<S> JsonParseErrors<S> {
    pub fn new(inner: S) -> Self {
        JsonParseErrors {
            inner,
            pending: Vec::new(),
            written: 0,
        }
    }
}

/// The answer that replaces `head` if it is one of hyper's bare 4xx
/// answers: a whole response head with `content-length: 0` and no
/// `content-type`, as the first thing in a write.
fn replacement(head: &[u8]) -> Option<Vec<u8>> {
    let text = std::str::from_utf8(head).ok()?;
    let rest = text.strip_prefix("HTTP/1.1 4")?;
    if !text.ends_with("\r\n\r\n") {
        return None;
    }
    let lower = text.to_ascii_lowercase();
    if !lower.contains("\r\ncontent-length: 0\r\n") || lower.contains("\r\ncontent-type:") {
        return None;
    }
    let status_line = text.split("\r\n").next()?;
    let code = format!("4{}", rest.get(..2)?);
    let (error, message) = match code.as_str() {
        "431" => (
            "headers_too_large",
            "the request head is larger than the service reads",
        ),
        _ => (
            "malformed_request",
            "the request line or a header is not valid HTTP/1.1 (a path must percent-encode characters such as `<`, `>`, `\"`, `{`, `}` and spaces)",
        ),
    };
    let body = serde_json::json!({"error": {"code": error, "message": message, "field": null}})
        .to_string();
    Some(
        format!(
            "{status_line}\r\ncontent-type: application/json\r\ncontent-length: {}\r\nconnection: close\r\n\r\n{body}",
            body.len()
        )
        .into_bytes(),
    )
}

impl<S: AsyncWrite + Unpin> JsonParseErrors<S> {
    /// Writes what is left of a replacement answer.
    fn drain(&mut self, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        while self.written < self.pending.len() {
            let n =
                ready!(Pin::new(&mut self.inner).poll_write(cx, &self.pending[self.written..]))?;
            if n == 0 {
                return Poll::Ready(Err(io::ErrorKind::WriteZero.into()));
            }
            self.written += n;
        }
        self.pending.clear();
        self.written = 0;
        Poll::Ready(Ok(()))
    }

    /// Takes `head` (all `len` bytes of a write) as replaced, if it is one
    /// of hyper's bare answers; the replacement is written from here on.
    fn replace(
        &mut self,
        cx: &mut Context<'_>,
        head: &[u8],
        len: usize,
    ) -> Option<io::Result<usize>> {
        let answer = replacement(head)?;
        self.pending = answer;
        self.written = 0;
        // What cannot be written now is written by the flush hyper sends next.
        match self.drain(cx) {
            Poll::Ready(Err(err)) => Some(Err(err)),
            _ => Some(Ok(len)),
        }
    }
}

impl<S: AsyncRead + Unpin> AsyncRead for JsonParseErrors<S> {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_read(cx, buf)
    }
}

impl<S: AsyncWrite + Unpin> AsyncWrite for JsonParseErrors<S> {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        ready!(self.drain(cx))?;
        if let Some(done) = self.replace(cx, buf, buf.len()) {
            return Poll::Ready(done);
        }
        Pin::new(&mut self.inner).poll_write(cx, buf)
    }

    fn poll_write_vectored(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        ready!(self.drain(cx))?;
        let len = bufs.iter().map(|b| b.len()).sum();
        // hyper's bare answers have no body: their head is the whole write.
        if let [head, rest @ ..] = bufs
            && rest.iter().all(|b| b.is_empty())
            && let Some(done) = self.replace(cx, head, len)
        {
            return Poll::Ready(done);
        }
        Pin::new(&mut self.inner).poll_write_vectored(cx, bufs)
    }

    fn is_write_vectored(&self) -> bool {
        self.inner.is_write_vectored()
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        ready!(self.drain(cx))?;
        Pin::new(&mut self.inner).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        ready!(self.drain(cx))?;
        Pin::new(&mut self.inner).poll_shutdown(cx)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_bare_4xx_heads_are_replaced() {
        let bare = b"HTTP/1.1 400 Bad Request\r\nconnection: close\r\ncontent-length: 0\r\ndate: Fri, 04 Dec 2026 07:19:43 GMT\r\n\r\n";
        let answer = String::from_utf8(replacement(bare).unwrap()).unwrap();
        assert!(
            answer.starts_with("HTTP/1.1 400 Bad Request\r\n"),
            "{answer}"
        );
        let body = answer.split("\r\n\r\n").nth(1).unwrap();
        let json: serde_json::Value = serde_json::from_str(body).unwrap();
        assert_eq!(json["error"]["code"], "malformed_request");
        assert!(answer.contains(&format!("content-length: {}\r\n", body.len())));
        let too_large = b"HTTP/1.1 431 Request Header Fields Too Large\r\nconnection: close\r\ncontent-length: 0\r\n\r\n";
        assert!(
            String::from_utf8(replacement(too_large).unwrap())
                .unwrap()
                .contains("headers_too_large")
        );
        for kept in [
            &b"HTTP/1.1 400 Bad Request\r\ncontent-type: application/json\r\ncontent-length: 0\r\n\r\n"[..],
            b"HTTP/1.1 404 Not Found\r\ncontent-length: 12\r\n\r\n",
            b"HTTP/1.1 304 Not Modified\r\ncontent-length: 0\r\n\r\n",
            b"HTTP/1.1 400 Bad Request\r\ncontent-length: 0\r\n",
            b"{\"not\": \"a head\"}",
        ] {
            assert!(replacement(kept).is_none(), "{}", String::from_utf8_lossy(kept));
        }
    }
}
