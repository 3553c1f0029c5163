//! `dollop send`, `jog` and `valve` end to end over the in-memory link: load the config,
//! upload, home, start and follow a job to its end; move and test a valve by hand.

use dollop::wire::Mode;
use dollop::RunState;
use dollop_host::cmd::link::{
    jog_on, send_on, valve_on, AxisArg, JogArgs, LossArg, OnOff, PortArgs, SendArgs, ValveArgs,
};
use dollop_host::link::job::zigzag;
use dollop_host::link::{mem_options, Client, Faults, MemLink, BENCH_CONFIG};

fn port() -> PortArgs {
    PortArgs { port: None }
}

#[test]
fn send_loads_the_config_uploads_homes_prints_and_follows_to_the_end() {
    let dir = tempfile::tempdir().unwrap();
    let cfg_path = dir.path().join("machine.toml");
    std::fs::write(&cfg_path, BENCH_CONFIG).unwrap();
    let config: dollop::Config = toml::from_str(BENCH_CONFIG).unwrap();
    let job = zigzag(&config, 150);
    let job_path = dir.path().join("job.dlp");
    std::fs::write(&job_path, job.to_bytes()).unwrap();
    let read = dollop_host::link::JobFile::read(&job_path).unwrap();
    assert_eq!(read.body, job.body);

    let mut c = Client::new(MemLink::new(Faults::default(), 5), mem_options(), 5);
    c.connect().unwrap();
    let args = SendArgs {
        job: job_path,
        port: port(),
        config: Some(cfg_path),
        on_link_loss: LossArg::Pause,
        upload_only: false,
    };
    send_on(&mut c, &read, &args).unwrap();
    let s = c.status().unwrap();
    assert_eq!(s.control.run, RunState::Done);
    assert_eq!(s.control.mode, Mode::Idle);
    assert_eq!(c.transport().board().out.valves, 0);
}

#[test]
fn send_without_a_config_says_how_to_give_one() {
    let config: dollop::Config = toml::from_str(BENCH_CONFIG).unwrap();
    let job = zigzag(&config, 10);
    let mut c = Client::new(MemLink::new(Faults::default(), 6), mem_options(), 6);
    c.connect().unwrap();
    let args = SendArgs {
        job: "job.dlp".into(),
        port: port(),
        config: None,
        on_link_loss: LossArg::Stop,
        upload_only: true,
    };
    let e = send_on(&mut c, &job, &args).unwrap_err();
    assert!(e.to_string().contains("--config"), "{e}");
}

#[test]
fn a_corrupt_job_file_is_refused_before_anything_is_sent() {
    let config: dollop::Config = toml::from_str(BENCH_CONFIG).unwrap();
    let mut bytes = zigzag(&config, 50).to_bytes();
    let n = bytes.len();
    bytes[n - 3] ^= 0x20;
    let e = dollop_host::link::JobFile::parse(&bytes).unwrap_err();
    assert!(
        e.to_string().contains("corrupt") || e.to_string().contains("decode"),
        "{e}"
    );
    let e = dollop_host::link::JobFile::parse(&bytes[..n - 10]).unwrap_err();
    assert!(e.to_string().contains("bytes"), "{e}");
    assert!(dollop_host::link::JobFile::parse(b"not a job").is_err());
}

#[test]
fn jog_and_valve_by_hand() {
    let config: dollop::Config = toml::from_str(BENCH_CONFIG).unwrap();
    let mut c = Client::new(MemLink::new(Faults::default(), 8), mem_options(), 8);
    c.connect().unwrap();
    c.command(&dollop::wire::Request::LoadConfig(config))
        .unwrap();
    c.sleep(std::time::Duration::from_millis(1));
    let home = JogArgs {
        port: port(),
        axis: None,
        mm: None,
        home: true,
    };
    jog_on(&mut c, &home).unwrap();
    let x0 = c.status().unwrap().control.position_um[0];
    let jog = JogArgs {
        port: port(),
        axis: Some(AxisArg::X),
        mm: Some(12.5),
        home: false,
    };
    jog_on(&mut c, &jog).unwrap();
    assert_eq!(c.status().unwrap().control.position_um[0], x0 + 12_500);
    let too_far = JogArgs {
        port: port(),
        axis: Some(AxisArg::X),
        mm: Some(-500.0),
        home: false,
    };
    let e = jog_on(&mut c, &too_far).unwrap_err();
    assert!(e.to_string().contains("outside its travel"), "{e}");
    let v = ValveArgs {
        port: port(),
        inlet: 1,
        state: OnOff::On,
        seconds: Some(1.0),
    };
    valve_on(&mut c, &v).unwrap();
    let board = c.transport().board();
    assert_eq!(board.out.valves, 0, "closed after the test");
    assert!(board.out.valve_changes >= 2);
    let bad = ValveArgs {
        port: port(),
        inlet: 7,
        state: OnOff::On,
        seconds: Some(0.1),
    };
    let e = valve_on(&mut c, &bad).unwrap_err();
    assert!(e.to_string().contains("does not exist"), "{e}");
}
