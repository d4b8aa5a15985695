//! The README's Slurm recipe for real: a private single-node Slurm cluster (munged, slurmctld
//! and slurmd from Debian's `slurm-wlm` and `munge`, started here with their own key, socket,
//! ports and spool in a temporary folder, and stopped at the end) runs
//! `docs/cluster/render.sbatch` as a job array of three shards and `docs/cluster/merge.sbatch`
//! after it (`--dependency=afterok`); the merged PNG must be the unsharded render's byte for
//! byte. scripts/test installs the packages.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The cluster's daemons, stopped when dropped.
struct Cluster {
    dir: tempfile::TempDir,
    daemons: Vec<Child>,
    conf: PathBuf,
}

impl Drop for Cluster {
    fn drop(&mut self) {
        for d in &mut self.daemons {
            let _ = d.kill();
            let _ = d.wait();
        }
    }
}

fn tool(name: &str) -> PathBuf {
    for dir in ["/usr/sbin", "/usr/bin", "/sbin", "/bin"] {
        let p = Path::new(dir).join(name);
        if p.exists() {
            return p;
        }
    }
    panic!("this test needs {name}: apt-get install slurm-wlm munge (scripts/test does)");
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

fn output(cmd: &mut Command) -> String {
    let out = cmd.output().unwrap_or_else(|e| panic!("{cmd:?}: {e}"));
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "{cmd:?} failed:\n{text}");
    text
}

fn logs(dir: &Path) -> String {
    ["munged.log", "slurmctld.log", "slurmd.log"]
        .iter()
        .map(|f| {
            let t = std::fs::read_to_string(dir.join(f)).unwrap_or_default();
            let tail: Vec<&str> = t.lines().rev().take(15).collect();
            format!(
                "--- {f}\n{}",
                tail.into_iter().rev().collect::<Vec<_>>().join("\n")
            )
        })
        .collect::<Vec<_>>()
        .join("\n")
}

impl Cluster {
    fn start() -> Cluster {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let user = output(Command::new("id").arg("-un")).trim().to_string();
        let host = output(Command::new("hostname").arg("-s"))
            .trim()
            .to_string();
        let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
        // munge: a key of our own, its socket in the folder.
        let key = d.join("munge.key");
        output(
            Command::new(tool("mungekey"))
                .arg("--create")
                .arg("--keyfile")
                .arg(&key),
        );
        let socket = d.join("munge.socket");
        let munged = Command::new(tool("munged"))
            .arg("--foreground")
            .arg("--force")
            .arg(format!("--socket={}", socket.display()))
            .arg(format!("--key-file={}", key.display()))
            .arg(format!("--pid-file={}", d.join("munged.pid").display()))
            .arg(format!("--log-file={}", d.join("munged.log").display()))
            .arg(format!("--seed-file={}", d.join("munged.seed").display()))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let mut cluster = Cluster {
            conf: d.join("slurm.conf"),
            daemons: vec![munged],
            dir,
        };
        let d = cluster.dir.path().to_path_buf();
        std::fs::create_dir_all(d.join("state")).unwrap();
        std::fs::create_dir_all(d.join("spool")).unwrap();
        let conf = format!(
            "ClusterName=termtrace\nSlurmctldHost={host}(127.0.0.1)\nSlurmUser={user}\n\
             SlurmdUser={user}\nSlurmctldPort={}\nSlurmdPort={}\nAuthType=auth/munge\n\
             AuthInfo=socket={}\nCryptoType=crypto/munge\nProctrackType=proctrack/linuxproc\n\
             TaskPlugin=task/none\nSchedulerType=sched/builtin\nSelectType=select/cons_tres\n\
             SelectTypeParameters=CR_Core\nReturnToService=2\nMpiDefault=none\n\
             StateSaveLocation={d}/state\nSlurmdSpoolDir={d}/spool\n\
             SlurmctldPidFile={d}/slurmctld.pid\nSlurmdPidFile={d}/slurmd.pid\n\
             SlurmctldLogFile={d}/slurmctld.log\nSlurmdLogFile={d}/slurmd.log\n\
             JobCompType=jobcomp/none\nJobAcctGatherType=jobacct_gather/none\n\
             AccountingStorageType=accounting_storage/none\n\
             NodeName={host} NodeAddr=127.0.0.1 CPUs={cpus} RealMemory=1000 State=UNKNOWN\n\
             PartitionName=ci Nodes={host} Default=YES MaxTime=INFINITE State=UP\n",
            free_port(),
            free_port(),
            socket.display(),
            d = d.display(),
        );
        std::fs::write(&cluster.conf, conf).unwrap();
        // munged makes its socket; the daemons need it.
        let t = Instant::now();
        while !socket.exists() {
            assert!(
                t.elapsed() < Duration::from_secs(20),
                "munged did not start:\n{}",
                logs(&d)
            );
            std::thread::sleep(Duration::from_millis(100));
        }
        for daemon in ["slurmctld", "slurmd"] {
            let child = Command::new(tool(daemon))
                .arg("-D")
                .arg("-f")
                .arg(&cluster.conf)
                .env("SLURM_CONF", &cluster.conf)
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .unwrap();
            cluster.daemons.push(child);
        }
        // Until the node is idle.
        let t = Instant::now();
        loop {
            let out = cluster
                .command("sinfo")
                .args(["-h", "-o", "%t"])
                .output()
                .unwrap();
            if String::from_utf8_lossy(&out.stdout).trim() == "idle" {
                break;
            }
            assert!(
                t.elapsed() < Duration::from_secs(60),
                "the Slurm node did not become idle:\n{}",
                logs(&d)
            );
            std::thread::sleep(Duration::from_millis(500));
        }
        cluster
    }

    /// A Slurm command of this cluster, with termtrace's binary on the PATH.
    fn command(&self, name: &str) -> Command {
        let mut c = Command::new(tool(name));
        let bin = Path::new(env!("CARGO_BIN_EXE_termtrace")).parent().unwrap();
        let path = format!(
            "{}:{}",
            bin.display(),
            std::env::var("PATH").unwrap_or_default()
        );
        c.env("SLURM_CONF", &self.conf).env("PATH", path);
        c
    }
}

#[test]
fn the_readme_slurm_recipe_merges_to_the_unsharded_render_bit_for_bit() {
    let cluster = Cluster::start();
    let work = tempfile::tempdir().unwrap();
    let w = work.path();
    let render = root().join("docs/cluster/render.sbatch");
    let merge = root().join("docs/cluster/merge.sbatch");
    let size = ["--width", "24", "--height", "16", "--adapter", "cpu-native"];
    let job = output(
        cluster
            .command("sbatch")
            .current_dir(w)
            .args(["--parsable", "--array=0-2"])
            .arg(&render)
            .args(["cornell", "9"])
            .args(size),
    );
    let job = job.trim().to_string();
    output(
        cluster
            .command("sbatch")
            .current_dir(w)
            .args(["--parsable", "--wait"])
            .arg(format!("--dependency=afterok:{job}"))
            .arg(&merge)
            .arg("merged.png"),
    );
    let parts: Vec<String> = std::fs::read_dir(w.join("parts"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(parts.len(), 3, "{parts:?}\n{}", logs(cluster.dir.path()));
    output(
        Command::new(env!("CARGO_BIN_EXE_termtrace"))
            .current_dir(w)
            .args(["render", "cornell", "--spp", "9", "-o", "whole.png", "-q"])
            .args(size),
    );
    let merged = std::fs::read(w.join("merged.png"))
        .unwrap_or_else(|e| panic!("no merged image ({e}):\n{}", logs(cluster.dir.path())));
    assert_eq!(merged, std::fs::read(w.join("whole.png")).unwrap());
}
