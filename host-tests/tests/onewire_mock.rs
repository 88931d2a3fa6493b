//! The 1-Wire bus and DS18B20 driver against embedded-hal-mock pin and delay
//! transactions: every pin call and delay is expected, in order, with the datasheet
//! timing constants.

use embedded_hal_mock::eh1::delay::{CheckedDelay, Transaction as D};
use embedded_hal_mock::eh1::digital::{Mock as PinMock, State, Transaction as P};
use embedded_hal_mock::eh1::MockError;
use qfa_thermal::ds18b20::{crc8, encode_scratchpad, Resolution};
use qfa_thermal::ds18b20_driver::{self as drv, Ds18b20};
use qfa_thermal::onewire::{self as ow, OneWire, Rom};

/// The expected pin and delay transactions of a bus conversation.
#[derive(Default)]
struct Script {
    pin: Vec<P>,
    delay: Vec<D>,
}

impl Script {
    fn reset(&mut self, presence: bool) -> &mut Self {
        self.pin.extend([P::set(State::High), P::get(State::High), P::set(State::Low)]);
        self.delay.push(D::delay_us(480));
        self.pin.push(P::set(State::High));
        self.delay.push(D::delay_us(70));
        self.pin.push(P::get(if presence { State::Low } else { State::High }));
        self.delay.push(D::delay_us(410));
        self.pin.push(P::get(State::High));
        self
    }

    fn write_bit(&mut self, bit: bool) -> &mut Self {
        let (low, rest) = if bit { (6, 64) } else { (60, 10) };
        self.pin.push(P::set(State::Low));
        self.delay.push(D::delay_us(low));
        self.pin.push(P::set(State::High));
        self.delay.push(D::delay_us(rest));
        self
    }

    fn read_bit(&mut self, bit: bool) -> &mut Self {
        self.pin.push(P::set(State::Low));
        self.delay.push(D::delay_us(2));
        self.pin.push(P::set(State::High));
        self.delay.push(D::delay_us(8));
        self.pin.push(P::get(if bit { State::High } else { State::Low }));
        self.delay.push(D::delay_us(55));
        self
    }

    fn write(&mut self, bytes: &[u8]) -> &mut Self {
        for &b in bytes {
            for i in 0..8 {
                self.write_bit(b & (1 << i) != 0);
            }
        }
        self
    }

    fn read(&mut self, bytes: &[u8]) -> &mut Self {
        for &b in bytes {
            for i in 0..8 {
                self.read_bit(b & (1 << i) != 0);
            }
        }
        self
    }

    fn bus(&self) -> OneWire<PinMock, CheckedDelay> {
        OneWire::new(PinMock::new(&self.pin), CheckedDelay::new(&self.delay))
    }
}

fn done(bus: OneWire<PinMock, CheckedDelay>) {
    let (mut pin, mut delay) = bus.free();
    pin.done();
    delay.done();
}

#[test]
fn reset_with_presence() {
    let mut bus = Script::default().reset(true).bus();
    assert_eq!(bus.reset(), Ok(()));
    assert_eq!(bus.reset_count(), 1);
    assert_eq!(bus.elapsed_us(), 960);
    done(bus);
}

#[test]
fn reset_without_presence() {
    let mut bus = Script::default().reset(false).bus();
    assert_eq!(bus.reset(), Err(ow::Error::NoPresence));
    assert_eq!(bus.reset_count(), 0);
    done(bus);
}

#[test]
fn reset_on_a_line_already_low_is_stuck_low() {
    let s = Script { pin: vec![P::set(State::High), P::get(State::Low)], delay: vec![] };
    let mut bus = s.bus();
    assert_eq!(bus.reset(), Err(ow::Error::BusStuckLow));
    done(bus);
}

#[test]
fn line_still_low_after_presence_window_is_stuck_low() {
    let mut s = Script::default();
    s.reset(true);
    *s.pin.last_mut().unwrap() = P::get(State::Low);
    let mut bus = s.bus();
    assert_eq!(bus.reset(), Err(ow::Error::BusStuckLow));
    done(bus);
}

#[test]
fn pin_error_is_typed() {
    let s =
        Script { pin: vec![P::set(State::High).with_error(MockError::Io(std::io::ErrorKind::Other))], delay: vec![] };
    let mut bus = s.bus();
    assert_eq!(bus.reset(), Err(ow::Error::Pin));
    done(bus);
}

#[test]
fn write_byte_is_lsb_first_with_datasheet_slots() {
    // A5h = 1010_0101b: bits sent 1,0,1,0,0,1,0,1.
    let mut s = Script::default();
    for bit in [true, false, true, false, false, true, false, true] {
        s.write_bit(bit);
    }
    let mut bus = s.bus();
    bus.write_byte(0xA5).unwrap();
    assert_eq!(bus.elapsed_us(), 8 * 70);
    done(bus);
}

#[test]
fn read_byte_is_lsb_first() {
    let mut bus = Script::default().read(&[0x3C, 0x81]).bus();
    assert_eq!(bus.read_byte(), Ok(0x3C));
    assert_eq!(bus.read_byte(), Ok(0x81));
    assert_eq!(bus.elapsed_us(), 16 * 65);
    done(bus);
}

const ROM: [u8; 8] = [0x28, 0xFF, 0x64, 0x1E, 0x0F, 0x16, 0x03, 0];

fn rom_bytes() -> [u8; 8] {
    let mut r = ROM;
    r[7] = crc8(&r[..7]);
    r
}

#[test]
fn read_rom_checks_crc() {
    let rom = rom_bytes();
    let mut bus = Script::default().reset(true).write(&[0x33]).read(&rom).bus();
    let got = bus.read_rom().unwrap();
    assert_eq!(got.bytes(), rom);
    assert_eq!(got.family(), 0x28);
    done(bus);

    let mut bad = rom;
    bad[3] ^= 0x10;
    let mut bus = Script::default().reset(true).write(&[0x33]).read(&bad).bus();
    assert_eq!(bus.read_rom(), Err(ow::Error::RomCrc { computed: crc8(&bad[..7]), read: rom[7] }));
    done(bus);
}

#[test]
fn rom_checks() {
    assert_eq!(Rom::from_bytes([0; 8]), Err(ow::Error::RomAllZero));
    let mut other = [0x10, 1, 2, 3, 4, 5, 6, 0];
    other[7] = crc8(&other[..7]);
    let other = Rom::from_bytes(other).unwrap();
    assert_eq!(other.require_family(0x28), Err(ow::Error::WrongFamily(0x10)));
    assert_eq!(Ds18b20::new(other), Err(drv::Error::WrongFamily(0x10)));
    assert_eq!(Rom::from_bytes(rom_bytes()).unwrap().to_string(), format!("28FF641E0F1603{:02X}", rom_bytes()[7]));
}

#[test]
fn full_convert_and_read_cycle_with_match_rom() {
    let rom = rom_bytes();
    let sp = encode_scratchpad(0x0191, Resolution::Bits12, 0x0F);
    let mut s = Script::default();
    s.reset(true).write(&[0x55]).write(&rom).write(&[0x44]);
    s.reset(true).write(&[0x55]).write(&rom).write(&[0xBE]).read(&sp);
    let mut bus = s.bus();
    let mut sensor = Ds18b20::new(Rom::from_bytes(rom).unwrap()).unwrap();

    assert_eq!(sensor.read(&mut bus), Err(drv::Error::NotStarted));
    sensor.start(&mut bus, 1_000).unwrap();
    // Timer mode: no bus traffic until the 750 ms maximum has passed.
    assert_eq!(sensor.is_ready(&mut bus, 1_000 + 749_999), Ok(false));
    assert_eq!(sensor.read(&mut bus), Err(drv::Error::NotReady));
    assert_eq!(sensor.is_ready(&mut bus, 1_000 + 750_000), Ok(true));
    let sample = sensor.read(&mut bus).unwrap();
    assert_eq!(sample.reading.celsius(), 25.0625);
    assert_eq!(sample.scratchpad, sp);
    assert_eq!(sample.completed_us, 751_000);
    assert_eq!(sensor.read(&mut bus), Err(drv::Error::NotStarted), "a sample is read once");
    done(bus);
}

#[test]
fn crc_error_is_retried_then_succeeds() {
    let good = encode_scratchpad(-0x00A2, Resolution::Bits12, 0x0F);
    let mut bad = good;
    bad[1] ^= 0x80;
    let mut s = Script::default();
    s.reset(true).write(&[0xCC, 0x44]);
    s.reset(true).write(&[0xCC, 0xBE]).read(&bad);
    s.reset(true).write(&[0xCC, 0xBE]).read(&good);
    let mut bus = s.bus();
    let mut sensor = Ds18b20::single().with_retries(1);
    sensor.start(&mut bus, 0).unwrap();
    assert!(sensor.is_ready(&mut bus, 750_000).unwrap());
    assert_eq!(sensor.read(&mut bus).unwrap().reading.celsius(), -10.125);
    done(bus);
}

#[test]
fn set_resolution_writes_and_verifies() {
    let before = [0x50, 0x05, 0x4B, 0x46, 0x7F, 0xFF, 0x0C, 0x10, 0x1C];
    let mut after = [0x50, 0x05, 0x4B, 0x46, 0x3F, 0xFF, 0x0C, 0x10, 0];
    after[8] = crc8(&after[..8]);
    let mut s = Script::default();
    s.reset(true).write(&[0xCC, 0xBE]).read(&before);
    s.reset(true).write(&[0xCC, 0x4E, 0x4B, 0x46, 0x3F]);
    s.reset(true).write(&[0xCC, 0xBE]).read(&after);
    let mut bus = s.bus();
    let mut sensor = Ds18b20::single();
    sensor.set_resolution(&mut bus, Resolution::Bits10).unwrap();
    assert_eq!(sensor.resolution(), Resolution::Bits10);
    done(bus);

    // The device ignores the write: verification fails with the config read.
    let mut s = Script::default();
    s.reset(true).write(&[0xCC, 0xBE]).read(&before);
    s.reset(true).write(&[0xCC, 0x4E, 0x4B, 0x46, 0x3F]);
    s.reset(true).write(&[0xCC, 0xBE]).read(&before);
    let mut bus = s.bus();
    let mut sensor = Ds18b20::single();
    assert_eq!(sensor.set_resolution(&mut bus, Resolution::Bits10), Err(drv::Error::Verify(0x7F)));
    assert_eq!(sensor.resolution(), Resolution::Bits12);
    done(bus);
}

#[test]
fn read_power_supply() {
    let mut s = Script::default();
    s.reset(true).write(&[0xCC, 0xB4]).read_bit(false);
    s.reset(true).write(&[0xCC, 0xB4]).read_bit(true);
    let mut bus = s.bus();
    let sensor = Ds18b20::single();
    assert_eq!(sensor.read_power_supply(&mut bus), Ok(drv::PowerSupply::Parasite));
    assert_eq!(sensor.read_power_supply(&mut bus), Ok(drv::PowerSupply::External));
    done(bus);
}
