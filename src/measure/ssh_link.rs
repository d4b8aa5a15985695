//! A real OpenSSH connection for `bench --preview --ssh` and its test: a throw-away `sshd` on
//! a free loopback port (its own host key, authorized key and configuration in a temporary
//! folder; of the system it only needs the privilege-separation folder that Debian's sshd
//! checks for), reached through a throttling TCP proxy (a rate and a one-way delay in each
//! direction), and the `ssh -tt` command that runs termtrace through it.

use super::MeasureError;
use std::io::{Read, Write};
use std::net::{Shutdown, TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Where Debian's openssh-server installs the daemon.
pub const SSHD: &str = "/usr/sbin/sshd";

pub struct SshLink {
    dir: tempfile::TempDir,
    sshd: Child,
    proxy_port: u16,
    user: String,
}

fn free_port() -> Result<u16, MeasureError> {
    Ok(TcpListener::bind("127.0.0.1:0")?.local_addr()?.port())
}

fn run(cmd: &mut Command) -> Result<String, MeasureError> {
    let out = cmd
        .output()
        .map_err(MeasureError::io(format!("cannot run {cmd:?}")))?;
    if !out.status.success() {
        return Err(MeasureError::Failed {
            command: format!("{cmd:?}"),
            stderr: String::from_utf8_lossy(&out.stderr).trim().to_string(),
        });
    }
    Ok(String::from_utf8_lossy(&out.stdout).trim().to_string())
}

/// Copies `src` to `dst` as a link of `bits_per_second` with `delay` one way: each piece
/// leaves when the link is free and arrives `delay` later. Ends at end of input.
fn throttle(mut src: TcpStream, mut dst: TcpStream, bits_per_second: f64, delay: Duration) {
    let (tx, rx) = std::sync::mpsc::channel::<(Instant, Vec<u8>)>();
    std::thread::spawn(move || {
        let mut buf = vec![0u8; 4096];
        let mut free = Instant::now();
        while let Ok(n) = src.read(&mut buf) {
            if n == 0 {
                break;
            }
            let now = Instant::now();
            free = free.max(now) + Duration::from_secs_f64(n as f64 * 8.0 / bits_per_second);
            if tx.send((free + delay, buf[..n].to_vec())).is_err() {
                break;
            }
        }
    });
    std::thread::spawn(move || {
        for (due, bytes) in rx {
            std::thread::sleep(due.saturating_duration_since(Instant::now()));
            if dst.write_all(&bytes).is_err() {
                break;
            }
        }
        let _ = dst.shutdown(Shutdown::Write);
    });
}

impl SshLink {
    /// Starts sshd and the proxy: `bits_per_second` each way and a round trip of `rtt`.
    pub fn start(bits_per_second: f64, rtt: Duration) -> Result<SshLink, MeasureError> {
        if !Path::new(SSHD).exists() {
            return Err(MeasureError::Link(format!(
                "{SSHD} is missing: apt-get install openssh-server openssh-client (.ci/run does)"
            )));
        }
        let dir = tempfile::tempdir()?;
        let d = dir.path();
        let keygen = |name: &str| {
            run(Command::new("ssh-keygen")
                .args(["-q", "-t", "ed25519", "-N", "", "-f"])
                .arg(d.join(name)))
        };
        keygen("host_key")?;
        keygen("user_key")?;
        std::fs::copy(d.join("user_key.pub"), d.join("authorized_keys"))?;
        let user = run(Command::new("id").arg("-un"))?;
        let port = free_port()?;
        let config = format!(
            "Port {port}\nListenAddress 127.0.0.1\nHostKey {d}/host_key\nPidFile {d}/sshd.pid\n\
             AuthorizedKeysFile {d}/authorized_keys\nStrictModes no\nUsePAM no\n\
             PasswordAuthentication no\nKbdInteractiveAuthentication no\n\
             PubkeyAuthentication yes\nPermitRootLogin prohibit-password\n\
             AllowTcpForwarding no\nX11Forwarding no\nPrintMotd no\nLogLevel ERROR\n",
            d = d.display()
        );
        std::fs::write(d.join("sshd_config"), config)?;
        // Debian's sshd refuses to start without its privilege-separation folder.
        if !Path::new("/run/sshd").exists() {
            let _ = std::fs::create_dir_all("/run/sshd");
        }
        let sshd = Command::new(SSHD)
            .args(["-D", "-e", "-f"])
            .arg(d.join("sshd_config"))
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(d.join("sshd.log"))?)
            .spawn()
            .map_err(MeasureError::io("cannot start sshd"))?;
        let mut link = SshLink {
            dir,
            sshd,
            proxy_port: 0,
            user,
        };
        let deadline = Instant::now() + Duration::from_secs(10);
        while TcpStream::connect(("127.0.0.1", port)).is_err() {
            if Instant::now() > deadline || link.sshd.try_wait()?.is_some() {
                let log =
                    std::fs::read_to_string(link.dir.path().join("sshd.log")).unwrap_or_default();
                return Err(MeasureError::Link(format!(
                    "sshd did not start on port {port}: {}",
                    log.trim()
                )));
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let proxy = TcpListener::bind("127.0.0.1:0")?;
        link.proxy_port = proxy.local_addr()?.port();
        let one_way = rtt / 2;
        std::thread::spawn(move || {
            for client in proxy.incoming() {
                let Ok(client) = client else { break };
                let Ok(server) = TcpStream::connect(("127.0.0.1", port)) else {
                    continue;
                };
                let _ = client.set_nodelay(true);
                let _ = server.set_nodelay(true);
                let (c2, s2) = match (client.try_clone(), server.try_clone()) {
                    (Ok(c), Ok(s)) => (c, s),
                    _ => continue,
                };
                throttle(client, server, bits_per_second, one_way);
                throttle(s2, c2, bits_per_second, one_way);
            }
        });
        Ok(link)
    }

    /// The command line that runs `remote` on the far side of the link, in a terminal.
    pub fn command(&self, remote: &[String]) -> Vec<String> {
        let key: PathBuf = self.dir.path().join("user_key");
        let mut c: Vec<String> = [
            "ssh",
            "-tt",
            "-p",
            &self.proxy_port.to_string(),
            "-i",
            &key.display().to_string(),
            "-o",
            "StrictHostKeyChecking=no",
            "-o",
            "UserKnownHostsFile=/dev/null",
            "-o",
            "BatchMode=yes",
            "-o",
            "LogLevel=ERROR",
            &format!("{}@127.0.0.1", self.user),
            "--",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        c.extend(remote.iter().cloned());
        c
    }
}

impl Drop for SshLink {
    fn drop(&mut self) {
        let _ = self.sshd.kill();
        let _ = self.sshd.wait();
    }
}
