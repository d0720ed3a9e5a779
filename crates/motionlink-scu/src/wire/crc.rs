//! CRC-16/XMODEM of SCU telegrams.

/// The CRC of SCU telegrams from the `crc` crate: CRC-16/XMODEM (polynomial 0x1021, initial value 0, no
/// reflection, no final xor), with its slice-by-16 tables.
pub const CRC: crc::Crc<u16, crc::Table<16>> = crc::Crc::<u16, crc::Table<16>>::new(&crc::CRC_16_XMODEM);

/// The `crc` crate's tables, built at compile time: `TABLES[k][b]` is the CRC of byte `b` followed by `k` zero
/// bytes. `TABLES[0]` is the manual's CRC_TABLE (chapter 6, code example 1).
static TABLES: [[u16; 256]; 16] = *CRC.table();

/// CRC-16/XMODEM of `bytes` (initial value 0, no reflection, no final xor), as the manual specifies.
///
/// Telegrams are short (4 to a few dozen bytes). [`CRC`]`.checksum` would take each 16-byte block in one step and
/// every byte after the last whole block one at a time, a long chain of dependent lookups for a 29-byte
/// telegram; this uses the same tables sixteen, eight and four bytes at a time. The tests check it against the `crc`
/// crate for every length, and against the manual's table.
///
/// ```
/// assert_eq!(motionlink_scu::wire::crc16(b"123456789"), 0x31C3);
/// ```
pub fn crc16(bytes: &[u8]) -> u16 {
    let t = &TABLES;
    let mut crc: u16 = 0;
    let mut blocks = bytes.chunks_exact(16);
    for c in &mut blocks {
        let [hi, lo] = crc.to_be_bytes();
        crc = (t[15][usize::from(c[0] ^ hi)]
            ^ t[14][usize::from(c[1] ^ lo)]
            ^ t[13][usize::from(c[2])]
            ^ t[12][usize::from(c[3])]
            ^ t[11][usize::from(c[4])]
            ^ t[10][usize::from(c[5])]
            ^ t[9][usize::from(c[6])]
            ^ t[8][usize::from(c[7])])
            ^ (t[7][usize::from(c[8])]
                ^ t[6][usize::from(c[9])]
                ^ t[5][usize::from(c[10])]
                ^ t[4][usize::from(c[11])]
                ^ t[3][usize::from(c[12])]
                ^ t[2][usize::from(c[13])]
                ^ t[1][usize::from(c[14])]
                ^ t[0][usize::from(c[15])]);
    }
    let mut chunks = blocks.remainder().chunks_exact(8);
    for c in &mut chunks {
        let [hi, lo] = crc.to_be_bytes();
        crc = t[7][usize::from(c[0] ^ hi)]
            ^ t[6][usize::from(c[1] ^ lo)]
            ^ t[5][usize::from(c[2])]
            ^ t[4][usize::from(c[3])]
            ^ t[3][usize::from(c[4])]
            ^ t[2][usize::from(c[5])]
            ^ t[1][usize::from(c[6])]
            ^ t[0][usize::from(c[7])];
    }
    let mut rest = chunks.remainder();
    if rest.len() >= 4 {
        let [hi, lo] = crc.to_be_bytes();
        crc = t[3][usize::from(rest[0] ^ hi)]
            ^ t[2][usize::from(rest[1] ^ lo)]
            ^ t[1][usize::from(rest[2])]
            ^ t[0][usize::from(rest[3])];
        rest = &rest[4..];
    }
    for &b in rest {
        crc = t[0][usize::from((crc >> 8) as u8 ^ b)] ^ (crc << 8);
    }
    crc
}

/// Continues a CRC over more bytes (byte by byte; for the rare unknown-command search).
pub(super) fn crc16_update(mut crc: u16, bytes: &[u8]) -> u16 {
    for &b in bytes {
        crc = TABLES[0][usize::from((crc >> 8) as u8 ^ b)] ^ (crc << 8);
    }
    crc
}
