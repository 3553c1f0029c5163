//! Set-up shared by the `dollop serve` tests: the server's arguments as a test starts it
//! (loopback on a free port, no USB, one simulated board fifty times faster than the wall
//! clock, no key, no data folder); each test changes what it is about.

use dollop_host::serve;

/// The arguments every test starts from.
pub fn args() -> serve::Args {
    serve::Args {
        listen: "127.0.0.1:0".parse().expect("address"),
        port: None,
        auth: None,
        config: None,
        boards: Vec::new(),
        demo: false,
        sim_speed: 50.0,
        no_usb: true,
        sim_boards: 1,
        data: None,
        camera: None,
    }
}
