//! Little-endian field readers for binary payloads (UBX, CASIC): `None` past the end of the payload, so
//! a message shorter than its documented layout is never read past its end.

pub(crate) fn u1(p: &[u8], o: usize) -> Option<u8> {
    p.get(o).copied()
}
pub(crate) fn i1(p: &[u8], o: usize) -> Option<i8> {
    p.get(o).map(|&b| i8::from_le_bytes([b]))
}
pub(crate) fn u2(p: &[u8], o: usize) -> Option<u16> {
    p.get(o..o + 2)?.try_into().ok().map(u16::from_le_bytes)
}
pub(crate) fn i2(p: &[u8], o: usize) -> Option<i16> {
    p.get(o..o + 2)?.try_into().ok().map(i16::from_le_bytes)
}
pub(crate) fn u4(p: &[u8], o: usize) -> Option<u32> {
    p.get(o..o + 4)?.try_into().ok().map(u32::from_le_bytes)
}
pub(crate) fn i4(p: &[u8], o: usize) -> Option<i32> {
    p.get(o..o + 4)?.try_into().ok().map(i32::from_le_bytes)
}
/// IEEE 754 single precision.
pub(crate) fn r4(p: &[u8], o: usize) -> Option<f32> {
    p.get(o..o + 4)?.try_into().ok().map(f32::from_le_bytes)
}
/// IEEE 754 double precision.
pub(crate) fn r8(p: &[u8], o: usize) -> Option<f64> {
    p.get(o..o + 8)?.try_into().ok().map(f64::from_le_bytes)
}
