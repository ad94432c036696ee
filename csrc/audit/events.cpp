// Impact events (rblog/analyze/events.py): contact groups chained across intervals.
#include <vector>

#include "audit/audit.hpp"

namespace rb {
namespace audit {

// Chain contact groups (ordered by interval gk) into events: a group continues the event of the
// group of the previous interval with the same key (member-set hash h, size, static feature sid,
// smallest member mem0), else starts one. A body is the smallest member of at most one group per
// interval, so that group is the last one seen with its mem0. Writes eid (C,) the event of each
// group, head_of (E,) its first group and k1 (E,) its last interval, events numbered as they
// start; returns E.
i64 link_groups(V1<i64> gk, V1<i64> h, V1<i64> size, V1<i64> sid, V1<i64> mem0, i64 n,
                V1<i64> eid, V1<i64> head_of, V1<i64> k1) {
    std::vector<i64> last(n, -1);
    i64 n_ev = 0;
    for (i64 g = 0; g < gk.n0; ++g) {
        const i64 m = mem0[g];
        const i64 p = last[m];
        i64 e;
        if (p >= 0 && gk[p] == gk[g] - 1 && h[p] == h[g] && size[p] == size[g] &&
            sid[p] == sid[g]) {
            e = eid[p];
        } else {
            e = n_ev;
            head_of[e] = g;
            n_ev += 1;
        }
        eid[g] = e;
        k1[e] = gk[g];
        last[m] = g;
    }
    return n_ev;
}

}  // namespace audit
}  // namespace rb
