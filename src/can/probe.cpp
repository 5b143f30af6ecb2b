// Bus scan of can_probe (see probe.h).
#include "massage_cell/can/probe.h"

#include <algorithm>
#include <cstdio>
#include <map>
#include <memory>
#include <set>
#include <sstream>

#include "massage_cell/can/cia402.h"
#include "massage_cell/can/sdo_client.h"

namespace massage_cell::can {

std::vector<std::uint8_t> parseNodeList(const std::string& text) {
  std::set<std::uint8_t> ids;
  std::stringstream s(text);
  auto number = [&](const std::string& part, const std::string& t) {
    if (t.empty() || t.find_first_not_of("0123456789") != std::string::npos) {
      throw std::invalid_argument("node list: '" + part + "' is not a node id or a range like 1-127");
    }
    const long v = std::stol(t);
    if (v < 1 || v > 127) throw std::invalid_argument("node list: " + t + " is outside 1..127");
    return static_cast<int>(v);
  };
  for (std::string part; std::getline(s, part, ',');) {
    if (part.empty()) continue;
    const auto dash = part.find('-');
    if (dash == std::string::npos) {
      ids.insert(static_cast<std::uint8_t>(number(part, part)));
      continue;
    }
    const int lo = number(part, part.substr(0, dash)), hi = number(part, part.substr(dash + 1));
    if (lo > hi) throw std::invalid_argument("node list: range '" + part + "' runs backwards");
    for (int i = lo; i <= hi; ++i) ids.insert(static_cast<std::uint8_t>(i));
  }
  if (ids.empty()) throw std::invalid_argument("node list: no node ids in '" + text + "'");
  return {ids.begin(), ids.end()};
}

std::vector<ProbeResult> probeNodes(Bus& bus, const ProbeOptions& options) {
  const Clock& clock = SteadyClock::instance();
  const TimePoint start = clock.now();
  std::map<std::uint8_t, std::unique_ptr<SdoClient>> clients;
  std::map<std::uint8_t, ProbeResult> found;
  std::map<std::uint8_t, NmtState> nmt;
  std::size_t outstanding = 0;
  auto client = [&](std::uint8_t node) -> SdoClient& {
    auto& c = clients[node];
    if (!c)
      c = std::make_unique<SdoClient>(
          node, [&bus](const can_frame& f) { return bus.send(f); }, clock, options.sdo_timeout);
    return *c;
  };
  auto pump = [&](Duration wait) {
    if (auto f = bus.receive(wait)) {
      const can_frame& fr = f->frame;
      if (auto r = decodeSdoResponse(fr)) {
        if (auto it = clients.find(r->node); it != clients.end()) it->second->handle(*r);
      } else if (auto h = decodeHeartbeat(fr)) {
        nmt[h->node] = h->state == NmtState::kBootUp ? NmtState::kPreOperational : h->state;
      }
    }
    for (auto& [id, c] : clients) c->poll();
  };

  // Phase 1: who is there (0x1000), a window of requests at a time.
  std::size_t next = 0;
  while (next < options.nodes.size() || outstanding > 0) {
    while (next < options.nodes.size() && outstanding < std::max<std::size_t>(1, options.in_flight)) {
      const std::uint8_t node = options.nodes[next++];
      ++outstanding;
      client(node).upload(0x1000, 0, [&, node](const SdoResult& r) {
        --outstanding;
        if (r.ok && r.data.size() == 4) {
          ProbeResult p;
          p.node = node;
          p.device_type = static_cast<std::uint32_t>(fromBytes(r.data));
          found[node] = p;
        } else if (!r.ok && r.abort_code != sdo_abort::kTimeout) {
          ProbeResult p;  // it answered, with an abort: still a node
          p.node = node;
          p.notes = "0x1000: " + r.error;
          found[node] = p;
        }
      });
    }
    pump(std::chrono::milliseconds(1));
  }
  // Phase 2: name and statusword of the nodes found.
  for (auto& [node, p] : found) {
    ++outstanding;
    client(node).upload(0x1008, 0, [&, node](const SdoResult& r) {
      --outstanding;
      if (r.ok) {
        found[node].device_name.assign(r.data.begin(), r.data.end());
      } else {
        found[node].notes += (found[node].notes.empty() ? "" : "; ") + std::string("no device name (") +
                             sdoAbortText(r.abort_code) + ")";
      }
    });
    ++outstanding;
    client(node).upload(0x6041, 0, [&, node](const SdoResult& r) {
      --outstanding;
      if (r.ok && r.data.size() == 2) {
        found[node].statusword = static_cast<std::uint16_t>(fromBytes(r.data));
      } else if (!r.ok) {
        found[node].notes +=
            (found[node].notes.empty() ? "" : "; ") + std::string("no statusword (") + sdoAbortText(r.abort_code) + ")";
      }
    });
  }
  while (outstanding > 0 || clock.now() - start < options.listen) pump(std::chrono::milliseconds(1));

  std::vector<ProbeResult> out;
  for (auto& [node, p] : found) {
    if (auto it = nmt.find(node); it != nmt.end()) p.nmt = it->second;
    out.push_back(p);
  }
  return out;
}

std::string formatProbeTable(const std::vector<ProbeResult>& results) {
  std::string out = "node  device type  NMT state        statusword                         device name\n";
  char buf[256];
  for (const ProbeResult& p : results) {
    std::string sw = "-";
    if (p.statusword) {
      std::snprintf(buf, sizeof buf, "0x%04X %s", *p.statusword, toString(decodeStatusword(*p.statusword)));
      sw = buf;
    }
    std::snprintf(buf, sizeof buf, "%4d  0x%08X   %-15s  %-33s  %s", p.node, p.device_type,
                  p.nmt ? toString(*p.nmt) : "no heartbeat", sw.c_str(),
                  p.device_name.empty() ? "-" : p.device_name.c_str());
    out += buf;
    if (!p.notes.empty()) out += "  [" + p.notes + "]";
    out += "\n";
  }
  return out;
}

}  // namespace massage_cell::can
