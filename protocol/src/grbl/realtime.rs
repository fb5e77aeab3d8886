//! grbl's realtime bytes: taken out of the stream the moment they arrive,
//! wherever they come, and never part of a line.

/// A byte that acts at once.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum GrblRealtime {
    /// `?`: one status report.
    StatusReport,
    /// `~`: cycle start, resume after a feed hold.
    CycleStart,
    /// `!`: feed hold, a deceleration along the path.
    FeedHold,
    /// 0x18 (Ctrl-X): soft reset.
    SoftReset,
    /// 0x84: safety door (treated as a feed hold: no door input).
    SafetyDoor,
    /// 0x85: jog cancel.
    JogCancel,
    /// 0x90: feed override back to 100 %.
    FeedReset,
    /// 0x91: feed override +10 %.
    FeedPlus10,
    /// 0x92: feed override −10 %.
    FeedMinus10,
    /// 0x93: feed override +1 %.
    FeedPlus1,
    /// 0x94: feed override −1 %.
    FeedMinus1,
    /// 0x95: rapid override 100 %.
    Rapid100,
    /// 0x96: rapid override 50 %.
    Rapid50,
    /// 0x97: rapid override 25 %.
    Rapid25,
    /// 0x99: spindle override back to 100 % (reported, no spindle).
    SpindleReset,
    /// 0x9A: spindle override +10 %.
    SpindlePlus10,
    /// 0x9B: spindle override −10 %.
    SpindleMinus10,
    /// 0x9C: spindle override +1 %.
    SpindlePlus1,
    /// 0x9D: spindle override −1 %.
    SpindleMinus1,
    /// 0x9E: spindle stop toggle (no spindle: ignored).
    SpindleStop,
    /// 0xA0: flood coolant toggle (ignored).
    FloodToggle,
    /// 0xA1: mist coolant toggle (ignored).
    MistToggle,
    /// Another byte of 0x80–0xFF: grbl keeps every such byte out of the
    /// line buffer and ignores the ones it does not know.
    Ignored(u8),
}

impl GrblRealtime {
    /// The realtime command a byte stands for, if it is one.
    pub fn from_byte(byte: u8) -> Option<Self> {
        use GrblRealtime::*;
        Some(match byte {
            b'?' => StatusReport,
            b'~' => CycleStart,
            b'!' => FeedHold,
            0x18 => SoftReset,
            0x84 => SafetyDoor,
            0x85 => JogCancel,
            0x90 => FeedReset,
            0x91 => FeedPlus10,
            0x92 => FeedMinus10,
            0x93 => FeedPlus1,
            0x94 => FeedMinus1,
            0x95 => Rapid100,
            0x96 => Rapid50,
            0x97 => Rapid25,
            0x99 => SpindleReset,
            0x9A => SpindlePlus10,
            0x9B => SpindleMinus10,
            0x9C => SpindlePlus1,
            0x9D => SpindleMinus1,
            0x9E => SpindleStop,
            0xA0 => FloodToggle,
            0xA1 => MistToggle,
            0x80..=0xFF => Ignored(byte),
            _ => return None,
        })
    }

    /// The byte that stands for it (the inverse of [`GrblRealtime::from_byte`]).
    pub fn byte(self) -> u8 {
        use GrblRealtime::*;
        match self {
            StatusReport => b'?',
            CycleStart => b'~',
            FeedHold => b'!',
            SoftReset => 0x18,
            SafetyDoor => 0x84,
            JogCancel => 0x85,
            FeedReset => 0x90,
            FeedPlus10 => 0x91,
            FeedMinus10 => 0x92,
            FeedPlus1 => 0x93,
            FeedMinus1 => 0x94,
            Rapid100 => 0x95,
            Rapid50 => 0x96,
            Rapid25 => 0x97,
            SpindleReset => 0x99,
            SpindlePlus10 => 0x9A,
            SpindleMinus10 => 0x9B,
            SpindlePlus1 => 0x9C,
            SpindleMinus1 => 0x9D,
            SpindleStop => 0x9E,
            FloodToggle => 0xA0,
            MistToggle => 0xA1,
            Ignored(byte) => byte,
        }
    }
}
