//! `cryofit healthcheck [--url URL] [--timeout SECS]`: exits 0 when a coordinator's `/healthz`
//! answers 200 with `{"status": "ok"}`, 1 otherwise. Meant for container health checks, where no
//! HTTP client may be installed: it speaks plain HTTP/1.1 over a std socket, without a runtime.

use std::io::{Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::Duration;

use anyhow::{Context, Result, anyhow, bail};
use clap::Args;

/// Arguments of `cryofit healthcheck`.
#[derive(Debug, Args)]
pub struct HealthcheckArgs {
    /// The health endpoint (plain `http://` only).
    #[arg(long, value_name = "URL", env = "CRYOFIT_HEALTHCHECK_URL", default_value = "http://127.0.0.1:8700/healthz")]
    url: String,
    /// Give up after this many seconds (connect, send and read each).
    #[arg(long, value_name = "SECS", default_value_t = 5.0)]
    timeout: f64,
}

/// Host, port and path of an `http://` URL.
fn split_url(url: &str) -> Result<(String, u16, String)> {
    let rest = url.strip_prefix("http://").ok_or_else(|| {
        anyhow!("--url {url}: give a plain http:// URL (check the coordinator itself, not a TLS proxy)")
    })?;
    let (authority, path) = match rest.find('/') {
        Some(i) => (&rest[..i], &rest[i..]),
        None => (rest, "/healthz"),
    };
    if authority.is_empty() {
        bail!("--url {url}: no host");
    }
    // [v6]:port, host:port or host
    let (host, port) = if let Some(v6) = authority.strip_prefix('[') {
        let (h, after) = v6.split_once(']').ok_or_else(|| anyhow!("--url {url}: unclosed '['"))?;
        (h.to_string(), after.strip_prefix(':'))
    } else {
        match authority.rsplit_once(':') {
            Some((h, p)) => (h.to_string(), Some(p)),
            None => (authority.to_string(), None),
        }
    };
    let port = match port {
        Some(p) => p.parse::<u16>().map_err(|_| anyhow!("--url {url}: port `{p}` is not a number in 0-65535"))?,
        None => 80,
    };
    Ok((host, port, path.to_string()))
}

/// `cryofit healthcheck`.
pub fn run(args: &HealthcheckArgs) -> Result<()> {
    if !(args.timeout.is_finite() && args.timeout > 0.0 && args.timeout <= 3600.0) {
        bail!("--timeout {}: give seconds in (0, 3600]", args.timeout);
    }
    let timeout = Duration::from_secs_f64(args.timeout);
    let (host, port, path) = split_url(&args.url)?;
    let addrs: Vec<_> = (host.as_str(), port)
        .to_socket_addrs()
        .with_context(|| format!("{}: cannot resolve {host}", args.url))?
        .collect();
    let mut last = None;
    let mut stream = None;
    for a in &addrs {
        match TcpStream::connect_timeout(a, timeout) {
            Ok(s) => {
                stream = Some(s);
                break;
            }
            Err(e) => last = Some(format!("{a}: {e}")),
        }
    }
    let mut stream = stream
        .ok_or_else(|| anyhow!("{}: cannot connect ({})", args.url, last.unwrap_or_else(|| "no address".into())))?;
    stream.set_read_timeout(Some(timeout))?;
    stream.set_write_timeout(Some(timeout))?;
    let host_header = if host.contains(':') { format!("[{host}]:{port}") } else { format!("{host}:{port}") };
    write!(
        stream,
        "GET {path} HTTP/1.1\r\nHost: {host_header}\r\nAccept: application/json\r\nConnection: close\r\n\r\n"
    )
    .with_context(|| format!("{}: cannot send the request", args.url))?;
    let mut reply = Vec::new();
    stream
        .take(64 * 1024)
        .read_to_end(&mut reply)
        .with_context(|| format!("{}: no complete answer within {} s", args.url, args.timeout))?;
    let text = String::from_utf8_lossy(&reply);
    let (head, body) = text.split_once("\r\n\r\n").ok_or_else(|| anyhow!("{}: not an HTTP answer", args.url))?;
    let status_line = head.lines().next().unwrap_or_default();
    let code = status_line.split_whitespace().nth(1).unwrap_or_default();
    if code != "200" {
        bail!("{}: answered `{status_line}`", args.url);
    }
    let health: cryofit_api::Health = serde_json::from_str(body.trim())
        .with_context(|| format!("{}: the body is not a health report: {}", args.url, body.trim()))?;
    if health.status != "ok" {
        bail!("{}: status `{}`", args.url, health.status);
    }
    println!("ok: {} (cryofit {})", args.url, health.version);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::split_url;

    #[test]
    fn urls_split_into_host_port_path() {
        assert_eq!(split_url("http://127.0.0.1:8700/healthz").unwrap(), ("127.0.0.1".into(), 8700, "/healthz".into()));
        assert_eq!(split_url("http://coordinator").unwrap(), ("coordinator".into(), 80, "/healthz".into()));
        assert_eq!(split_url("http://[::1]:9/x").unwrap(), ("::1".into(), 9, "/x".into()));
        assert!(split_url("https://a/healthz").is_err());
        assert!(split_url("http://a:99999/").is_err());
        assert!(split_url("http:///healthz").is_err());
    }
}
