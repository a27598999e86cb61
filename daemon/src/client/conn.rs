//! The control-plane client: one connection to `interpd serve` speaking the
//! line protocol of [`crate::protocol`] (one request per line, one reply
//! line per request, in order). [`Connection`] is async (tokio): `send`,
//! `demo` and `jitter` stream through it. [`BlockingConnection`] is the
//! same connection driven by a runtime of its own, for callers with no
//! runtime (the end-to-end tests, scripts).

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, Error, Result, anyhow, bail};
use tokio::io::{
    AsyncBufReadExt, AsyncRead, AsyncWrite, AsyncWriteExt, BufReader, Lines, ReadHalf, WriteHalf,
};

use crate::protocol::Reply;
use crate::service::control::StatusReply;

/// What a client says when the server is gone mid-conversation.
pub const GONE: &str = "the server closed the connection (it stopped or crashed)";

/// Where a server listens.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Endpoint {
    /// Loopback (or remote) TCP.
    Tcp(SocketAddr),
    /// A Unix socket.
    Unix(PathBuf),
}

impl core::fmt::Display for Endpoint {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Endpoint::Tcp(a) => write!(f, "{a}"),
            Endpoint::Unix(p) => write!(f, "{}", p.display()),
        }
    }
}

/// A byte stream a connection runs on (TCP or a Unix socket).
pub trait Io: AsyncRead + AsyncWrite + Unpin + Send {}
impl<T: AsyncRead + AsyncWrite + Unpin + Send> Io for T {}

/// One protocol connection.
pub struct Connection<S> {
    rd: Lines<BufReader<ReadHalf<S>>>,
    wr: WriteHalf<S>,
}

impl<S> core::fmt::Debug for Connection<S> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Connection").finish_non_exhaustive()
    }
}

/// Connects to `at` (TCP with no delay, or a Unix socket).
pub async fn connect(at: &Endpoint) -> Result<Connection<Box<dyn Io>>> {
    let io: Box<dyn Io> = match at {
        Endpoint::Tcp(a) => {
            let s = tokio::net::TcpStream::connect(a)
                .await
                .with_context(|| format!("connecting to {a}"))?;
            s.set_nodelay(true).ok();
            Box::new(s)
        }
        Endpoint::Unix(p) => Box::new(
            tokio::net::UnixStream::connect(p)
                .await
                .with_context(|| format!("connecting to {}", p.display()))?,
        ),
    };
    Ok(Connection::new(io))
}

impl<S: AsyncRead + AsyncWrite + Unpin> Connection<S> {
    /// A connection over `io`.
    pub fn new(io: S) -> Self {
        let (rd, wr) = tokio::io::split(io);
        Connection {
            rd: BufReader::new(rd).lines(),
            wr,
        }
    }

    /// Sends one request line (without waiting for its reply).
    pub async fn send_line(&mut self, line: &str) -> Result<()> {
        self.wr
            .write_all(format!("{line}\n").as_bytes())
            .await
            .context(GONE)
    }

    /// The next reply line as the server wrote it. Cancel-safe: a reply
    /// not read whole is read by the next call.
    pub async fn reply_line(&mut self) -> Result<String> {
        self.rd
            .next_line()
            .await
            .context(GONE)?
            .ok_or_else(|| anyhow!(GONE))
    }

    /// The next reply, typed. Cancel-safe as [`Self::reply_line`].
    pub async fn reply(&mut self) -> Result<Reply> {
        let line = self.reply_line().await?;
        Reply::parse(&line).map_err(Error::msg)
    }

    /// Sends `line` and returns its reply (no other request in flight).
    pub async fn request(&mut self, line: &str) -> Result<Reply> {
        self.send_line(line).await?;
        self.reply().await
    }

    /// `auth TOKEN`; an error if the server refuses it.
    pub async fn auth(&mut self, token: &str) -> Result<()> {
        match self.request(&format!("auth {token}")).await? {
            Reply::Auth | Reply::Ok => Ok(()),
            Reply::Err { problem, .. } => bail!("authentication failed: {problem}"),
            other => bail!("unexpected reply to auth: {other}"),
        }
    }

    /// The server's status.
    pub async fn status(&mut self) -> Result<StatusReply> {
        match self.request("status").await? {
            Reply::Status(s) => Ok(*s),
            other => bail!("unexpected reply to status: {other}"),
        }
    }
}

/// A [`Connection`] for callers without a runtime: each call runs on the
/// connection's own current-thread runtime, and fails after `timeout`.
pub struct BlockingConnection {
    rt: tokio::runtime::Runtime,
    conn: Connection<Box<dyn Io>>,
    timeout: Duration,
}

impl core::fmt::Debug for BlockingConnection {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("BlockingConnection")
            .field("timeout", &self.timeout)
            .finish_non_exhaustive()
    }
}

impl BlockingConnection {
    /// Connects to `at`; every later call fails after `timeout`.
    pub fn connect(at: &Endpoint, timeout: Duration) -> Result<Self> {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .context("starting the client's runtime")?;
        let conn = rt.block_on(async {
            tokio::time::timeout(timeout, connect(at))
                .await
                .map_err(|_| anyhow!("connecting to {at}: timed out after {timeout:?}"))?
        })?;
        Ok(BlockingConnection { rt, conn, timeout })
    }

    fn run<T>(
        &mut self,
        what: &str,
        f: impl AsyncFnOnce(&mut Connection<Box<dyn Io>>) -> Result<T>,
    ) -> Result<T> {
        let (conn, timeout) = (&mut self.conn, self.timeout);
        self.rt.block_on(async move {
            tokio::time::timeout(timeout, f(conn))
                .await
                .map_err(|_| anyhow!("{what}: no reply in {timeout:?}"))?
        })
    }

    /// [`Connection::send_line`].
    pub fn send_line(&mut self, line: &str) -> Result<()> {
        self.run("sending", async |c| c.send_line(line).await)
    }

    /// [`Connection::reply_line`].
    pub fn reply_line(&mut self) -> Result<String> {
        self.run("reading a reply", async |c| c.reply_line().await)
    }

    /// [`Connection::reply`].
    pub fn reply(&mut self) -> Result<Reply> {
        self.run("reading a reply", async |c| c.reply().await)
    }

    /// [`Connection::request`].
    pub fn request(&mut self, line: &str) -> Result<Reply> {
        self.run(line, async |c| c.request(line).await)
    }

    /// [`Connection::status`].
    pub fn status(&mut self) -> Result<StatusReply> {
        self.run("status", async |c| c.status().await)
    }
}
