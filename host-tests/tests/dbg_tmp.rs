use qfa_thermal::{Compensator, Config, Status};
#[test]
fn dbg() {
    let data: [u8; 28] =
        [0, 1, 68, 100, 244, 0, 112, 2, 79, 0, 56, 34, 16, 34, 175, 0, 104, 2, 40, 66, 40, 2, 176, 2, 0, 2, 188, 50];
    let good_table = host_tests::fuzzing::stream_table();
    let mut c = Compensator::<3, 32>::new(Config::default()).unwrap();
    let mut t_ms: u32 = u32::from_le_bytes([data[0], 0, 0, 0x80]);
    let mut raw: i16 = 352;
    for w in data.chunks(2) {
        let (op, arg) = (w[0], w[1]);
        match op % 8 {
            0 | 1 => {
                t_ms = t_ms.wrapping_add(u32::from(arg) * 40);
                raw = match arg % 16 {
                    0 => 0x0550,
                    1 => raw.wrapping_add(400),
                    _ => raw.wrapping_add(i16::from(arg as i8 % 3)),
                };
                println!("raw t={t_ms} raw={raw} -> {:?}", c.on_raw(t_ms, raw));
            }
            4 | 5 => {
                let dt = u32::from(arg) * 20_000 + u32::from(op);
                let out = c.cycle([1, 2, 3], dt);
                println!("cycle dt={dt} -> {:?} slow {:?}", out.status, c.status());
            }
            7 => {
                println!("table -> {:?} {:?}", c.load_table(&good_table), c.status());
            }
            _ => {}
        }
    }
    let _ = Status::empty();
}
