// The MCAP message encoder: the per-sample messages (rblog.State, rblog.Metrics,
// foxglove.FrameTransforms) of a whole block as complete MCAP Message records, and the
// rblog.Contacts messages of a block, written straight from the channels' bytes
// (rblog/record/mcap_writer.py prepares the templates and calls these kernels).
//
// Protobuf wire format, as protobuf's own serializer writes it: fields in number order, repeated
// fields packed (tag, varint length, the elements' little-endian bytes), proto3 zero scalars left
// out in the FrameTransforms' timestamps (the State and Metrics scalars are always written, which
// docs/log-format.md allows). An MCAP Message record is opcode 0x05, the record's length (u64,
// of what follows it), channel id (u16), sequence (u32, 0), log time and publish time (u64 ns,
// equal), then the message: 31 bytes of head.
//
// FrameTransforms: per body, field 1 (length-delimited) holding a FrameTransform: 1 timestamp
// {1 seconds, 2 nanos}, 2 parent "world", 3 child name, 4 translation {1 x, 2 y, 3 z},
// 5 rotation {1 x, 2 y, 3 z, 4 w}. Everything after the timestamp is constant per body but for
// the 7 doubles, so each body has a template of those bytes (rest[rest_start[i]:rest_start[i+1]])
// and the offsets of its doubles in it (dbl_off (N, 7)); the kernel copies the template, writes
// the sample's timestamp and the doubles.
//
// Every output buffer is sized by the caller for the most its messages take; the bindings check
// that bound once before the kernels run (the kernels themselves do not bounds-check). The
// kernels release the GIL.
#include <nanobind/nanobind.h>

#include <cstdint>
#include <cstring>
#include <string>
#include <utility>
#include <vector>

#include "common/py.hpp"

namespace rb {

using u8 = std::uint8_t;

namespace {

inline i64 put_varint(u8* out, i64 k, i64 value) {
    while (value >= 0x80) {
        out[k] = static_cast<u8>((value & 0x7F) | 0x80);
        value >>= 7;
        k += 1;
    }
    out[k] = static_cast<u8>(value);
    return k + 1;
}

inline i64 put_u64(u8* out, i64 k, i64 value) {
    for (int i = 0; i < 8; ++i) out[k + i] = static_cast<u8>((value >> (8 * i)) & 0xFF);
    return k + 8;
}

// Python's floor division and modulo (ns // 10**9, ns % 10**9), as the numba kernel computed them.
inline void floor_divmod(i64 a, i64 b, i64& q, i64& r) {
    q = a / b;
    r = a % b;
    if (r != 0 && ((r < 0) != (b < 0))) {
        q -= 1;
        r += b;
    }
}

// One FrameTransforms message at out[k:] (returns its end): log time `ns`; the bodies' doubles
// in wire order (x, y, z, qx, qy, qz, qw) are the bytes of dbl8 from byte d0, 56 per body.
i64 put_frame_transforms(u8* out, i64 k, i64 ns, const u8* dbl8, i64 d0, V1<u8> rest,
                         V1<i64> rest_start, V2<i64> dbl_off, u8* ts) {
    const i64 n = dbl_off.n0;
    i64 sec, nanos;
    floor_divmod(ns, 1000000000, sec, nanos);
    i64 lts = 0;  // proto3: zero fields are left out, as protobuf's own serializer does
    if (sec) {
        ts[0] = 0x08;
        lts = put_varint(ts, 1, sec);
    }
    if (nanos) {
        ts[lts] = 0x10;
        lts = put_varint(ts, lts + 1, nanos);
    }
    for (i64 i = 0; i < n; ++i) {
        const i64 r0 = rest_start[i], r1 = rest_start[i + 1];
        out[k] = 0x0A;  // FrameTransforms.transforms (field 1, length-delimited)
        k = put_varint(out, k + 1, 2 + lts + (r1 - r0));
        out[k] = 0x0A;  // FrameTransform.timestamp
        out[k + 1] = static_cast<u8>(lts);
        k += 2;
        for (i64 j = 0; j < lts; ++j) out[k + j] = ts[j];
        k += lts;
        std::memcpy(out + k, rest.p + r0, static_cast<size_t>(r1 - r0));
        for (int c = 0; c < 7; ++c)
            std::memcpy(out + k + dbl_off(i, c), dbl8 + d0 + 56 * i + 8 * c, 8);
        k += r1 - r0;
    }
    return k;
}

// As put_frame_transforms, the doubles read straight from the sample's position (N, 3) and
// quat_wxyz (N, 4) rows (wire order x, y, z, qx, qy, qz, qw: the same bytes _tf_doubles lays out).
i64 put_frame_transforms_pq(u8* out, i64 k, i64 ns, const double* pos, const double* quat,
                            V1<u8> rest, V1<i64> rest_start, V2<i64> dbl_off, u8* ts) {
    const i64 n = dbl_off.n0;
    i64 sec, nanos;
    floor_divmod(ns, 1000000000, sec, nanos);
    i64 lts = 0;
    if (sec) {
        ts[0] = 0x08;
        lts = put_varint(ts, 1, sec);
    }
    if (nanos) {
        ts[lts] = 0x10;
        lts = put_varint(ts, lts + 1, nanos);
    }
    for (i64 i = 0; i < n; ++i) {
        const i64 r0 = rest_start[i], r1 = rest_start[i + 1];
        out[k] = 0x0A;
        k = put_varint(out, k + 1, 2 + lts + (r1 - r0));
        out[k] = 0x0A;
        out[k + 1] = static_cast<u8>(lts);
        k += 2;
        for (i64 j = 0; j < lts; ++j) out[k + j] = ts[j];
        k += lts;
        std::memcpy(out + k, rest.p + r0, static_cast<size_t>(r1 - r0));
        const double* p = pos + 3 * i;
        const double* q = quat + 4 * i;
        const double* src[7] = {p, p + 1, p + 2, q + 1, q + 2, q + 3, q};
        for (int c = 0; c < 7; ++c) std::memcpy(out + k + dbl_off(i, c), src[c], 8);
        k += r1 - r0;
    }
    return k;
}

// One column of a block's samples as bytes: sample t's are `runs` runs of `run_bytes`
// contiguous bytes each, at p + t * row_stride + j * run_stride (a C-contiguous (T, bytes)
// column, or a row-contiguous one, is one run per sample; a (T, N, 3) view of a wider array,
// N runs).
struct ByteCol {
    const u8* p = nullptr;
    i64 n0 = 0, row_stride = 0, runs = 1, run_stride = 0, run_bytes = 0;
    i64 bytes() const { return runs * run_bytes; }
};

// Message of sample t whose every field is a header (tag, and length if packed) and that
// sample's bytes of one column.
i64 put_fields(u8* out, i64 k, i64 t, V1<u8> hdr, V1<i64> hdr_off, const std::vector<ByteCol>& cols) {
    for (size_t f = 0; f < cols.size(); ++f) {
        const i64 h0 = hdr_off[f], h1 = hdr_off[f + 1];
        std::memcpy(out + k, hdr.p + h0, static_cast<size_t>(h1 - h0));
        k += h1 - h0;
        const ByteCol& c = cols[f];
        const u8* src = c.p + t * c.row_stride;
        for (i64 j = 0; j < c.runs; ++j) {
            std::memcpy(out + k, src + j * c.run_stride, static_cast<size_t>(c.run_bytes));
            k += c.run_bytes;
        }
    }
    return k;
}

// Packed repeated field `number` holding elements lo..hi of src (little-endian bytes, `width`
// bytes per element).
i64 put_packed(u8* out, i64 k, int number, const u8* src, i64 lo, i64 hi, i64 width) {
    out[k] = static_cast<u8>((number << 3) | 2);
    const i64 n = (hi - lo) * width;
    k = put_varint(out, k + 1, n);
    std::memcpy(out + k, src + lo * width, static_cast<size_t>(n));
    return k + n;
}

}  // namespace

// Kernel of _TfEncoder.rows: writes T messages back to back into out; message t is
// out[bounds[t]:bounds[t + 1]]. dbl8: the (T, N, 7) doubles' bytes.
void encode_frame_transforms(V1<i64> ns, V1<u8> dbl8, V1<u8> rest, V1<i64> rest_start,
                             V2<i64> dbl_off, V1<u8> out, V1<i64> bounds) {
    u8 ts[24];
    const i64 per_sample = 56 * dbl_off.n0;
    i64 k = 0;
    for (i64 t = 0; t < ns.n0; ++t) {
        bounds[t] = k;
        k = put_frame_transforms(out.p, k, ns[t], dbl8.p, t * per_sample, rest, rest_start,
                                 dbl_off, ts);
    }
    bounds[ns.n0] = k;
}

// Kernel of _SampleRecords.encode: per sample, the State, Metrics and FrameTransforms Message
// records (opcode 0x05, length, channel, sequence 0, log time = publish time); record r ends at
// ends[r].
void encode_sample_records(V1<i64> ns, V1<i64> channels, V1<u8> st_hdr, V1<i64> st_off,
                           const std::vector<ByteCol>& st_cols, V1<u8> mt_hdr, V1<i64> mt_off,
                           const std::vector<ByteCol>& mt_cols, V1<u8> dbl8, V1<u8> rest,
                           V1<i64> rest_start, V2<i64> dbl_off, V1<u8> out, V1<i64> ends) {
    u8 ts[24];
    u8* o = out.p;
    const i64 per_sample = 56 * dbl_off.n0;
    i64 k = 0;
    i64 r = 0;
    for (i64 t = 0; t < ns.n0; ++t) {
        for (int m = 0; m < 3; ++m) {
            const i64 start = k;
            o[k] = 0x05;
            k = put_u64(o, k + 1, 0);  // the record's length, written below
            const i64 ch = channels[m];
            o[k] = static_cast<u8>(ch & 0xFF);
            o[k + 1] = static_cast<u8>((ch >> 8) & 0xFF);
            o[k + 2] = o[k + 3] = o[k + 4] = o[k + 5] = 0;
            k = put_u64(o, k + 6, ns[t]);
            k = put_u64(o, k, ns[t]);
            if (m == 0)
                k = put_fields(o, k, t, st_hdr, st_off, st_cols);
            else if (m == 1)
                k = put_fields(o, k, t, mt_hdr, mt_off, mt_cols);
            else
                k = put_frame_transforms(o, k, ns[t], dbl8.p, t * per_sample, rest, rest_start,
                                         dbl_off, ts);
            put_u64(o, start + 1, k - start - 9);
            ends[r] = k;
            r += 1;
        }
    }
}

// The same records, written straight into an MCAP chunk buffer (_BlockChunkBuilder): from
// record r0 (record r is message r % 3 of sample r / 3) at chunk[count:], record after record,
// until the chunk holds more than chunk_size bytes (the record that takes it past stays in it,
// as mcap's Writer closes chunks) or every record is written, or fewer than rec_max bytes are
// left in the buffer. offsets[r - r0] gets each record's offset in the chunk. Returns (the
// first record not written, the chunk's new byte count).
std::pair<i64, i64> encode_sample_records_into(
    i64 r0, V1<u8> chunk, i64 count, i64 chunk_size, i64 rec_max, V1<i64> ns, V1<i64> channels,
    V1<u8> st_hdr, V1<i64> st_off, const std::vector<ByteCol>& st_cols, V1<u8> mt_hdr,
    V1<i64> mt_off, const std::vector<ByteCol>& mt_cols, V3<double> position,
    V3<double> quat_wxyz, V1<u8> rest, V1<i64> rest_start, V2<i64> dbl_off, V1<i64> offsets) {
    u8 ts[24];
    u8* o = chunk.p;
    i64 k = count;
    i64 r = r0;
    const i64 n_rec = 3 * ns.n0;
    while (r < n_rec && k + rec_max <= chunk.n0) {
        const i64 t = r / 3;
        const int m = static_cast<int>(r % 3);
        const i64 start = k;
        offsets[r - r0] = k;
        o[k] = 0x05;
        k = put_u64(o, k + 1, 0);  // the record's length, written below
        const i64 ch = channels[m];
        o[k] = static_cast<u8>(ch & 0xFF);
        o[k + 1] = static_cast<u8>((ch >> 8) & 0xFF);
        o[k + 2] = o[k + 3] = o[k + 4] = o[k + 5] = 0;
        k = put_u64(o, k + 6, ns[t]);
        k = put_u64(o, k, ns[t]);
        if (m == 0)
            k = put_fields(o, k, t, st_hdr, st_off, st_cols);
        else if (m == 1)
            k = put_fields(o, k, t, mt_hdr, mt_off, mt_cols);
        else
            k = put_frame_transforms_pq(o, k, ns[t], &position(t, 0, 0), &quat_wxyz(t, 0, 0),
                                        rest, rest_start, dbl_off, ts);
        put_u64(o, start + 1, k - start - 9);
        r += 1;
        if (k > chunk_size) break;
    }
    return {r, k};
}

// Kernel of encode_contacts: message j holds contacts bounds[j]:bounds[j + 1] and is written to
// out[ends[j]:ends[j + 1]]. Inputs are the columns' bytes.
void encode_contacts(V1<i64> bounds, V1<u8> step8, V1<u8> t8, V1<u8> a4, V1<u8> b4,
                     V1<u8> point8, V1<u8> normal8, V1<u8> sep8, V1<u8> nimp8, V1<u8> fimp8,
                     V1<u8> kind4, V1<u8> out, V1<i64> ends) {
    u8* o = out.p;
    i64 k = 0;
    for (i64 j = 0; j < bounds.n0 - 1; ++j) {
        const i64 lo = bounds[j], hi = bounds[j + 1];
        ends[j] = k;
        o[k] = 0x09;  // 1 step, sfixed64
        std::memcpy(o + k + 1, step8.p + 8 * lo, 8);
        o[k + 9] = 0x11;  // 2 t, double
        std::memcpy(o + k + 10, t8.p + 8 * lo, 8);
        k += 18;
        k = put_packed(o, k, 3, a4.p, lo, hi, 4);
        k = put_packed(o, k, 4, b4.p, lo, hi, 4);
        k = put_packed(o, k, 5, point8.p, lo, hi, 24);
        k = put_packed(o, k, 6, normal8.p, lo, hi, 24);
        k = put_packed(o, k, 7, sep8.p, lo, hi, 8);
        k = put_packed(o, k, 8, nimp8.p, lo, hi, 8);
        k = put_packed(o, k, 9, fimp8.p, lo, hi, 24);
        k = put_packed(o, k, 10, kind4.p, lo, hi, 4);
    }
    ends[bounds.n0 - 1] = k;
}

// Kernel of put_records: record i is head[i] (hw bytes) then data[ends[i]:ends[i + 1]], written
// at out[start[i]:] (_BlockChunkBuilder.add_messages: MCAP Message records of a run).
void put_records(V2<u8> head, V1<u8> data, V1<i64> ends, V1<u8> out, V1<i64> start) {
    const i64 m = head.n0, hw = head.n1;
    for (i64 i = 0; i < m; ++i) {
        u8* o = out.p + start[i];
        std::memcpy(o, head.p + hw * i, hw);
        std::memcpy(o + hw, data.p + ends[i], ends[i + 1] - ends[i]);
    }
}

// --- bindings: argument checks (the kernels index without bounds checks) --------------------

namespace {

namespace nb = nanobind;

void need(bool ok, const std::string& what) {
    if (!ok) throw nb::value_error(what.c_str());
}

// The /tf templates: consistent among themselves; returns the most bytes one message takes.
i64 check_tf(V1<u8> rest, V1<i64> rest_start, V2<i64> dbl_off, const char* fn) {
    const i64 n = dbl_off.n0;
    need(dbl_off.n1 == 7 && rest_start.n0 == n + 1, std::string(fn) + ": dbl_off (N, 7) and rest_start (N + 1,) expected");
    for (i64 i = 0; i < n; ++i) {
        const i64 len = rest_start[i + 1] - rest_start[i];
        need(rest_start[i] >= 0 && len >= 0 && rest_start[i + 1] <= rest.n0,
             std::string(fn) + ": rest_start out of the template's bounds");
        for (int c = 0; c < 7; ++c)
            need(dbl_off(i, c) >= 0 && dbl_off(i, c) + 8 <= len,
                 std::string(fn) + ": dbl_off outside the body's template");
    }
    // per transform: its tag and length (<= 11 bytes), the timestamp's tag and length (2), a
    // timestamp of <= 17 bytes
    return (n ? rest_start[n] - rest_start[0] : 0) + 30 * n;
}

// Offsets of a header array consistent with it and with `n_fields` fields; returns its bytes.
i64 check_hdr(V1<u8> hdr, V1<i64> off, size_t n_fields, const char* what) {
    need(off.n0 == static_cast<i64>(n_fields) + 1, std::string(what) + ": one header per column expected");
    for (i64 f = 0; f + 1 < off.n0; ++f)
        need(off[f] >= 0 && off[f] <= off[f + 1] && off[f + 1] <= hdr.n0,
             std::string(what) + ": header offsets out of bounds");
    return off.n0 ? off[off.n0 - 1] - off[0] : 0;
}

// The columns of `seq`: uint8 arrays (T, bytes) or (T, runs, run bytes), each sample's bytes
// contiguous along the last axis, any strides before it (views, not copies).
std::vector<ByteCol> byte_cols(nb::handle seq, i64 T, const char* what, i64& row_bytes) {
    std::vector<ByteCol> cols;
    row_bytes = 0;
    for (nb::handle h : seq) {
        nb::ndarray<u8, nb::device::cpu> a;
        if (!nb::try_cast(h, a, false) || (a.ndim() != 2 && a.ndim() != 3) ||
            (a.shape(a.ndim() - 1) > 1 && a.stride(a.ndim() - 1) != 1))
            throw nb::type_error((std::string(what) + ": expected uint8 columns (T, bytes) or "
                                  "(T, runs, bytes), contiguous along the last axis").c_str());
        ByteCol c;
        c.p = a.data();
        c.n0 = static_cast<i64>(a.shape(0));
        c.row_stride = static_cast<i64>(a.stride(0));
        if (a.ndim() == 2) {
            c.run_bytes = static_cast<i64>(a.shape(1));
        } else {
            c.runs = static_cast<i64>(a.shape(1));
            c.run_stride = static_cast<i64>(a.stride(1));
            c.run_bytes = static_cast<i64>(a.shape(2));
            if (c.runs <= 1 || c.run_stride == c.run_bytes) {  // the runs are back to back
                c.run_bytes *= c.runs;
                c.runs = 1;
            }
        }
        need(c.n0 == T, std::string(what) + ": a column of another number of samples");
        cols.push_back(c);
        row_bytes += c.bytes();
    }
    return cols;
}

}  // namespace

void bind_mcap_encode(nb::module_& m) {
    m.def(
        "encode_frame_transforms",
        [](nb::handle ns_, nb::handle dbl8_, nb::handle rest_, nb::handle rest_start_,
           nb::handle dbl_off_, nb::handle out_, nb::handle bounds_) {
            auto ns = v1<i64>(ns_, "ns");
            auto dbl8 = v1<u8>(dbl8_, "dbl8");
            auto rest = v1<u8>(rest_, "rest");
            auto rest_start = v1<i64>(rest_start_, "rest_start");
            auto dbl_off = v2<i64>(dbl_off_, "dbl_off");
            auto out = v1<u8>(out_, "out");
            auto bounds = v1<i64>(bounds_, "bounds");
            const i64 T = ns.n0;
            const i64 cap = check_tf(rest, rest_start, dbl_off, "encode_frame_transforms");
            need(dbl8.n0 >= T * 56 * dbl_off.n0, "encode_frame_transforms: dbl8 too short");
            need(out.n0 >= T * cap, "encode_frame_transforms: out too small");
            need(bounds.n0 >= T + 1, "encode_frame_transforms: bounds too small");
            nb::gil_scoped_release release;
            encode_frame_transforms(ns, dbl8, rest, rest_start, dbl_off, out, bounds);
        },
        "Kernel of _TfEncoder.rows (rblog.record.mcap_writer). Releases the GIL.");

    m.def(
        "encode_sample_records",
        [](nb::handle ns_, nb::handle channels_, nb::handle st_hdr_, nb::handle st_off_,
           nb::handle st_cols_, nb::handle mt_hdr_, nb::handle mt_off_, nb::handle mt_cols_,
           nb::handle dbl8_, nb::handle rest_, nb::handle rest_start_, nb::handle dbl_off_,
           nb::handle out_, nb::handle ends_) {
            auto ns = v1<i64>(ns_, "ns");
            auto channels = v1<i64>(channels_, "channels");
            auto st_hdr = v1<u8>(st_hdr_, "st_hdr");
            auto st_off = v1<i64>(st_off_, "st_off");
            auto mt_hdr = v1<u8>(mt_hdr_, "mt_hdr");
            auto mt_off = v1<i64>(mt_off_, "mt_off");
            auto dbl8 = v1<u8>(dbl8_, "dbl8");
            auto rest = v1<u8>(rest_, "rest");
            auto rest_start = v1<i64>(rest_start_, "rest_start");
            auto dbl_off = v2<i64>(dbl_off_, "dbl_off");
            auto out = v1<u8>(out_, "out");
            auto ends = v1<i64>(ends_, "ends");
            const i64 T = ns.n0;
            i64 st_row = 0, mt_row = 0;
            auto st_cols = byte_cols(st_cols_, T, "st_cols", st_row);
            auto mt_cols = byte_cols(mt_cols_, T, "mt_cols", mt_row);
            need(channels.n0 == 3, "encode_sample_records: three channel ids expected");
            const i64 st_len = check_hdr(st_hdr, st_off, st_cols.size(), "st_hdr") + st_row;
            const i64 mt_len = check_hdr(mt_hdr, mt_off, mt_cols.size(), "mt_hdr") + mt_row;
            const i64 tf_len = check_tf(rest, rest_start, dbl_off, "encode_sample_records");
            need(dbl8.n0 >= T * 56 * dbl_off.n0, "encode_sample_records: dbl8 too short");
            need(out.n0 >= T * (3 * 31 + st_len + mt_len + tf_len),
                 "encode_sample_records: out too small");
            need(ends.n0 >= 3 * T, "encode_sample_records: ends too small");
            nb::gil_scoped_release release;
            encode_sample_records(ns, channels, st_hdr, st_off, st_cols, mt_hdr, mt_off, mt_cols,
                                  dbl8, rest, rest_start, dbl_off, out, ends);
        },
        "Kernel of _SampleRecords.encode (rblog.record.mcap_writer). Releases the GIL.");

    m.def(
        "encode_sample_records_into",
        [](i64 r0, nb::handle chunk_, i64 count, i64 chunk_size, nb::handle ns_,
           nb::handle channels_, nb::handle st_hdr_, nb::handle st_off_, nb::handle st_cols_,
           nb::handle mt_hdr_, nb::handle mt_off_, nb::handle mt_cols_, nb::handle position_,
           nb::handle quat_, nb::handle rest_, nb::handle rest_start_, nb::handle dbl_off_,
           nb::handle offsets_) {
            auto chunk = v1<u8>(chunk_, "chunk");
            auto ns = v1<i64>(ns_, "ns");
            auto channels = v1<i64>(channels_, "channels");
            auto st_hdr = v1<u8>(st_hdr_, "st_hdr");
            auto st_off = v1<i64>(st_off_, "st_off");
            auto mt_hdr = v1<u8>(mt_hdr_, "mt_hdr");
            auto mt_off = v1<i64>(mt_off_, "mt_off");
            auto position = v3<double>(position_, "position");
            auto quat = v3<double>(quat_, "quat_wxyz");
            auto rest = v1<u8>(rest_, "rest");
            auto rest_start = v1<i64>(rest_start_, "rest_start");
            auto dbl_off = v2<i64>(dbl_off_, "dbl_off");
            auto offsets = v1<i64>(offsets_, "offsets");
            const i64 T = ns.n0, n = dbl_off.n0;
            i64 st_row = 0, mt_row = 0;
            auto st_cols = byte_cols(st_cols_, T, "st_cols", st_row);
            auto mt_cols = byte_cols(mt_cols_, T, "mt_cols", mt_row);
            need(channels.n0 == 3, "encode_sample_records_into: three channel ids expected");
            const i64 st_len = check_hdr(st_hdr, st_off, st_cols.size(), "st_hdr") + st_row;
            const i64 mt_len = check_hdr(mt_hdr, mt_off, mt_cols.size(), "mt_hdr") + mt_row;
            const i64 tf_len = check_tf(rest, rest_start, dbl_off, "encode_sample_records_into");
            need(position.n0 == T && position.n1 == n && position.n2 == 3 && quat.n0 == T &&
                     quat.n1 == n && quat.n2 == 4,
                 "encode_sample_records_into: position (T, N, 3) and quat_wxyz (T, N, 4) expected");
            need(r0 >= 0 && r0 <= 3 * T, "encode_sample_records_into: r0 out of range");
            need(count >= 0 && count <= chunk.n0, "encode_sample_records_into: count out of range");
            need(offsets.n0 >= 3 * T - r0, "encode_sample_records_into: offsets too small");
            i64 rec_max = st_len > mt_len ? st_len : mt_len;
            rec_max = 31 + (rec_max > tf_len ? rec_max : tf_len);
            std::pair<i64, i64> res;
            {
                nb::gil_scoped_release release;
                res = encode_sample_records_into(r0, chunk, count, chunk_size, rec_max, ns,
                                                 channels, st_hdr, st_off, st_cols, mt_hdr,
                                                 mt_off, mt_cols, position, quat, rest,
                                                 rest_start, dbl_off, offsets);
            }
            return nb::make_tuple(res.first, res.second);
        },
        "The per-sample records straight into a chunk buffer (_BlockChunkBuilder."
        "add_sample_records): returns (next record, new byte count). Releases the GIL.");

    m.def(
        "put_records",
        [](nb::handle head_, nb::handle data_, nb::handle ends_, nb::handle out_,
           nb::handle start_) {
            auto head = v2<u8>(head_, "head");
            auto data = v1<u8>(data_, "data");
            auto ends = v1<i64>(ends_, "ends");
            auto out = v1<u8>(out_, "out");
            auto start = v1<i64>(start_, "start");
            const i64 m_ = head.n0;
            need(ends.n0 == m_ + 1 && start.n0 == m_, "put_records: ends (M + 1,), start (M,)");
            for (i64 i = 0; i < m_; ++i) {
                need(ends[i] >= 0 && ends[i] <= ends[i + 1] && ends[i + 1] <= data.n0,
                     "put_records: ends must rise within data");
                need(start[i] >= 0 && start[i] + head.n1 + ends[i + 1] - ends[i] <= out.n0,
                     "put_records: a record past the end of out");
            }
            nb::gil_scoped_release release;
            put_records(head, data, ends, out, start);
        },
        "MCAP records head[i] + data[ends[i]:ends[i + 1]] at out[start[i]:] (_BlockChunkBuilder."
        "add_messages). Releases the GIL.");

    m.def(
        "encode_contacts",
        [](nb::handle bounds_, nb::handle step8_, nb::handle t8_, nb::handle a4_, nb::handle b4_,
           nb::handle point8_, nb::handle normal8_, nb::handle sep8_, nb::handle nimp8_,
           nb::handle fimp8_, nb::handle kind4_, nb::handle out_, nb::handle ends_) {
            auto bounds = v1<i64>(bounds_, "bounds");
            auto step8 = v1<u8>(step8_, "step8");
            auto t8 = v1<u8>(t8_, "t8");
            auto a4 = v1<u8>(a4_, "a4");
            auto b4 = v1<u8>(b4_, "b4");
            auto point8 = v1<u8>(point8_, "point8");
            auto normal8 = v1<u8>(normal8_, "normal8");
            auto sep8 = v1<u8>(sep8_, "sep8");
            auto nimp8 = v1<u8>(nimp8_, "nimp8");
            auto fimp8 = v1<u8>(fimp8_, "fimp8");
            auto kind4 = v1<u8>(kind4_, "kind4");
            auto out = v1<u8>(out_, "out");
            auto ends = v1<i64>(ends_, "ends");
            need(bounds.n0 >= 1, "encode_contacts: bounds (M + 1,) expected");
            const i64 m_ = bounds.n0 - 1, n = bounds[m_];
            need(bounds[0] >= 0, "encode_contacts: bounds must start at 0 or more");
            for (i64 j = 0; j < m_; ++j)
                need(bounds[j] <= bounds[j + 1], "encode_contacts: bounds must not decrease");
            need(step8.n0 >= 8 * n && t8.n0 >= 8 * n && a4.n0 >= 4 * n && b4.n0 >= 4 * n &&
                     kind4.n0 >= 4 * n && point8.n0 >= 24 * n && normal8.n0 >= 24 * n &&
                     fimp8.n0 >= 24 * n && sep8.n0 >= 8 * n && nimp8.n0 >= 8 * n,
                 "encode_contacts: a column shorter than the contacts");
            need(out.n0 >= m_ * (18 + 8 * 11) + (n - bounds[0]) * (3 * 4 + 11 * 8),
                 "encode_contacts: out too small");
            need(ends.n0 >= m_ + 1, "encode_contacts: ends too small");
            nb::gil_scoped_release release;
            encode_contacts(bounds, step8, t8, a4, b4, point8, normal8, sep8, nimp8, fimp8, kind4,
                            out, ends);
        },
        "Kernel of encode_contacts (rblog.record.mcap_writer). Releases the GIL.");
}

}  // namespace rb
