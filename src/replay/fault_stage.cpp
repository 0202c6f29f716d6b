#include "replay/fault_stage.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string_view>

namespace wiretape::detail {

namespace {

// Amounts of the kinds whose amount is optional, when none is given
// (docs/faults.md).
constexpr std::uint64_t kDefaultGarbage = 8;
constexpr std::uint64_t kDefaultTrickleMs = 1;

std::string bytes_of(const RxItem& item) { return std::string(item.payload()); }

// A record a fault makes: at the time of `model`, in its exchange.
RxItem made_like(const RxItem& model, RecordKind kind, std::string data) {
  RxItem made;
  made.kind = kind;
  made.data = std::move(data);
  made.t_ns = model.t_ns;
  made.due = model.due;
  made.exchange = model.exchange;
  return made;
}

void set_bytes(RxItem& item, std::string bytes) {
  item.view = PayloadView{};
  item.data = std::move(bytes);
  item.consumed = 0;
}

}  // namespace

FaultInjector::FaultInjector(FaultPlan plan, bool datagrams, Reporter reporter,
                             std::shared_ptr<FaultMemory> memory, double speed)
    : plan_(std::move(plan)),
      datagrams_(datagrams),
      reporter_(std::move(reporter)),
      memory_(memory ? std::move(memory) : std::make_shared<FaultMemory>()),
      speed_(speed) {
  memory_->once_fired.resize(plan_.faults.size(), false);
}

std::uint64_t FaultInjector::draw(std::size_t index, std::uint64_t exchange,
                                  std::uint64_t purpose) const {
  return splitmix64(splitmix64(splitmix64(plan_.seed ^ 0x5741495245544150ULL) + index) +
                    exchange * 0x10001ULL + purpose);
}

bool FaultInjector::fires(std::size_t index, const FaultSpec& spec, std::uint64_t exchange,
                          const RxItem& item, std::uint64_t offset) {
  const bool starts_exchange = !current_exchange_ || *current_exchange_ != exchange;
  switch (spec.where) {
    case FaultWhereKind::exchange:
      return starts_exchange && exchange == spec.where_number;
    case FaultWhereKind::every:
      return starts_exchange && (exchange + 1) % spec.where_number == 0;
    case FaultWhereKind::probability: {
      if (!starts_exchange) return false;
      const double unit = static_cast<double>(draw(index, exchange, 0) >> 11) * 0x1.0p-53;
      return unit < spec.where_value;
    }
    case FaultWhereKind::rx: {
      if (memory_->once_fired[index] || item.kind != RecordKind::rx) return false;
      const std::size_t size = item.payload().size() - item.consumed;
      if (spec.where_number >= offset + size) return false;
      memory_->once_fired[index] = true;
      return true;
    }
    case FaultWhereKind::time:
      if (memory_->once_fired[index] ||
          static_cast<double>(item.t_ns) < spec.where_value * 1e9) {
        return false;
      }
      memory_->once_fired[index] = true;
      return true;
  }
  return false;
}

void FaultInjector::report(const FaultSpec& spec, std::uint64_t exchange, std::string detail) {
  ++memory_->injected;
  if (reporter_) reporter_(FaultEvent{spec.kind_text, spec.where_text, std::move(detail), exchange});
}

void FaultInjector::apply(RxItem&& item, std::deque<FaultedRx>& out, ReplayTime now) {
  if (rest_unreachable()) return;  // nothing more reaches the client
  const std::uint64_t exchange = item.exchange;
  const std::uint64_t offset = memory_->rx_served;
  const bool starts_exchange = !current_exchange_ || *current_exchange_ != exchange;

  // The pieces the client gets instead of this record, in order.
  std::vector<RxItem> pieces;
  std::optional<ReplayTime> back_at;
  bool lost = false;  // the pieces are a loss of the device
  const auto where_in = [&](const RxItem& piece) {
    return " in exchange " + std::to_string(exchange) + " (rx byte " +
           std::to_string(offset) + ", " + std::to_string(piece.payload().size()) + " bytes)";
  };
  // The first piece's bytes become `bytes`; with none left, it is gone.
  const auto replace_first = [&pieces](std::string bytes) {
    if (bytes.empty()) {
      pieces.erase(pieces.begin());
    } else {
      set_bytes(pieces.front(), std::move(bytes));
    }
  };
  // Firing is decided before this record counts as the exchange's.
  std::vector<std::size_t> firing;
  for (std::size_t i = 0; i < plan_.faults.size(); ++i) {
    if (fires(i, plan_.faults[i], exchange, item, offset)) firing.push_back(i);
  }
  if (starts_exchange) {
    current_exchange_ = exchange;
    drop_rest_ = false;
    trickle_ms_.reset();
    trickled_ = false;
    shift_ = std::chrono::nanoseconds(0);
    released_at_ = now;
  }
  // Not earlier than the exchange's release, so that the waits below are
  // real in every timing mode; later records of the exchange keep their
  // own times (they may be released late, while a trickle still plays).
  item.due = std::max(item.due, released_at_);
  if (item.kind == RecordKind::rx) memory_->rx_served += item.payload().size() - item.consumed;
  if (drop_rest_ && item.kind == RecordKind::rx) return;
  pieces.push_back(std::move(item));

  for (const std::size_t index : firing) {
    const FaultSpec& spec = plan_.faults[index];
    if (pieces.empty() || lost) break;
    RxItem& first = pieces.front();
    const bool is_rx = first.kind == RecordKind::rx;
    switch (spec.kind) {
      case FaultKind::drop: {
        if (!is_rx) break;
        if (!spec.amount) {
          report(spec, exchange, "dropped the rest of the response" + where_in(first));
          pieces.clear();
          drop_rest_ = true;
        } else if (datagrams_) {
          report(spec, exchange, "dropped a datagram" + where_in(first));
          pieces.clear();
        } else {
          std::string bytes = bytes_of(first);
          const std::size_t n = std::min<std::uint64_t>(*spec.amount, bytes.size());
          const std::size_t at = bytes.size() == n ? 0 : draw(index, exchange, 1) % (bytes.size() - n + 1);
          bytes.erase(at, n);
          report(spec, exchange, "dropped " + std::to_string(n) + " bytes at rx byte " +
                                     std::to_string(offset + at) + where_in(first));
          replace_first(std::move(bytes));
        }
        break;
      }
      case FaultKind::corrupt: {
        if (!is_rx) break;
        std::string bytes = bytes_of(first);
        if (bytes.empty()) break;
        std::string detail = "flipped";
        const std::uint64_t flips = spec.amount.value_or(1);
        for (std::uint64_t f = 0; f < flips; ++f) {
          const std::uint64_t r = draw(index, exchange, 100 + f);
          const std::size_t at = r % bytes.size();
          const unsigned bit = static_cast<unsigned>((r >> 32) % 8);
          bytes[at] = static_cast<char>(bytes[at] ^ (1u << bit));
          if (f < 8) detail += " bit " + std::to_string(bit) + " of rx byte " + std::to_string(offset + at) + ",";
        }
        if (flips > 8) detail += " ...";
        if (detail.back() == ',') detail.pop_back();
        report(spec, exchange, detail + where_in(first));
        set_bytes(first, std::move(bytes));
        break;
      }
      case FaultKind::garbage: {
        if (!is_rx) break;
        const std::uint64_t n = spec.amount.value_or(kDefaultGarbage);
        std::string noise(n, '\0');
        for (std::uint64_t b = 0; b < n; ++b) {
          noise[b] = static_cast<char>(draw(index, exchange, 1000 + b) & 0xff);
        }
        if (datagrams_) {
          RxItem extra = made_like(first, RecordKind::rx, std::move(noise));
          report(spec, exchange, "sent a datagram of " + std::to_string(n) +
                                     " random bytes before the response" + where_in(first));
          pieces.insert(pieces.begin(), std::move(extra));
        } else {
          std::string bytes = bytes_of(first);
          const std::size_t at = draw(index, exchange, 2) % (bytes.size() + 1);
          bytes.insert(at, noise);
          report(spec, exchange, "inserted " + std::to_string(n) + " random bytes at rx byte " +
                                     std::to_string(offset + at) + where_in(first));
          set_bytes(first, std::move(bytes));
        }
        break;
      }
      case FaultKind::truncate: {
        if (!is_rx) break;
        std::string bytes = bytes_of(first);
        const std::size_t keep =
            std::min<std::uint64_t>(spec.amount.value_or(bytes.size() / 2), bytes.size());
        report(spec, exchange, "cut the response after " + std::to_string(keep) +
                                   " bytes" + where_in(first));
        bytes.resize(keep);
        if (!datagrams_) drop_rest_ = true;
        replace_first(std::move(bytes));
        break;
      }
      case FaultKind::duplicate: {
        if (!is_rx) break;
        RxItem copy =
            made_like(first, RecordKind::rx, std::string(first.payload().substr(first.consumed)));
        report(spec, exchange, "sent the record twice" + where_in(first));
        pieces.insert(pieces.begin() + 1, std::move(copy));
        break;
      }
      case FaultKind::delay:
        shift_ += wait_of(*spec.amount);
        report(spec, exchange, "delayed the response by " + std::to_string(*spec.amount) +
                                   " ms" + where_in(first));
        break;
      case FaultKind::stall: {
        if (!is_rx || datagrams_ || first.payload().size() < 2) {
          shift_ += wait_of(*spec.amount);
          report(spec, exchange, "stalled " + std::to_string(*spec.amount) +
                                     " ms before the record" + where_in(first));
          break;
        }
        std::string bytes = bytes_of(first);
        const std::size_t half = bytes.size() / 2;
        RxItem head = first;
        set_bytes(head, bytes.substr(0, half));
        set_bytes(first, bytes.substr(half));
        report(spec, exchange, "stalled " + std::to_string(*spec.amount) + " ms after rx byte " +
                                   std::to_string(offset + half) + where_in(first));
        // Every piece is shifted below; the head only by the shift before
        // the stall.
        head.due -= wait_of(*spec.amount);
        shift_ += wait_of(*spec.amount);
        pieces.insert(pieces.begin(), std::move(head));
        break;
      }
      case FaultKind::trickle:
        trickle_ms_ = spec.amount.value_or(kDefaultTrickleMs);
        report(spec, exchange, "one byte every " + std::to_string(*trickle_ms_) +
                                   " ms to the end of the response" + where_in(first));
        break;
      case FaultKind::silence:
        report(spec, exchange, "the device stopped answering" + where_in(first));
        memory_->silenced = true;
        memory_->silenced_by = spec.kind_text + "@" + spec.where_text;
        pieces.clear();
        break;
      case FaultKind::disconnect:
      case FaultKind::reconnect: {
        RxItem loss = made_like(first, RecordKind::device_lost, {});
        std::string text = "the device went away (fault " + spec.kind_text + "@" +
                           spec.where_text + ")";
        if (spec.kind == FaultKind::disconnect) {
          memory_->lost = text;
        } else {
          back_at = first.due + shift_ + wait_of(*spec.amount);
          drop_rest_ = true;
          text = "the device went away for " + std::to_string(*spec.amount) + " ms (fault " +
                 spec.kind_text + "@" + spec.where_text + ")";
        }
        report(spec, exchange, text + where_in(first));
        loss.data = std::move(text);
        pieces.clear();
        pieces.push_back(std::move(loss));
        lost = true;
        break;
      }
    }
  }

  for (RxItem& piece : pieces) {
    // A stall's head already carries its own shift (see above).
    piece.due += shift_;
    if (trickle_ms_ && piece.kind == RecordKind::rx && !datagrams_) {
      // Every byte after the exchange's first waits MS, also the first
      // byte of a later record of the response.
      const std::string_view bytes = piece.payload().substr(piece.consumed);
      const auto shift_before = shift_;
      for (const char byte : bytes) {
        RxItem one = made_like(piece, RecordKind::rx, std::string(1, byte));
        if (trickled_) shift_ += wait_of(*trickle_ms_);
        trickled_ = true;
        one.due += shift_ - shift_before;
        out.push_back(FaultedRx{std::move(one), std::nullopt});
      }
      continue;
    }
    if (trickle_ms_ && datagrams_ && piece.kind == RecordKind::rx) {
      shift_ += wait_of(*trickle_ms_);
    }
    const bool is_loss = piece.kind == RecordKind::device_lost && lost;
    out.push_back(FaultedRx{std::move(piece), is_loss ? back_at : std::nullopt});
  }
}


// --- the stage ------------------------------------------------------------------

std::chrono::nanoseconds FaultInjector::wait_of(std::uint64_t ms) const {
  return std::chrono::nanoseconds(
      std::llround(static_cast<double>(ms) * 1e6 / speed_));
}

FaultStage::FaultStage(const FaultPlan& plan, bool datagrams, ReleasedRx& released,
                       std::shared_ptr<FaultMemory> memory, double speed)
    : released_(released) {
  if (plan.empty()) return;
  if (memory && memory->lost) {
    // An earlier client session's disconnect: the device is still gone.
    RxItem loss;
    loss.kind = RecordKind::device_lost;
    loss.data = *memory->lost;
    loss.due = ReplayTime::min();  // due at once
    faulted_.push_back(FaultedRx{std::move(loss), std::nullopt});
  }
  injector_ = std::make_unique<FaultInjector>(
      plan, datagrams, [this](const FaultEvent& event) { report(event); }, std::move(memory),
      speed);
}

void FaultStage::report(const FaultEvent& event) const {
  if (reporter_) {
    reporter_(event);
    return;
  }
  std::fprintf(stderr, "wiretape: fault %s@%s: %s\n", event.kind.c_str(), event.where.c_str(),
               event.detail.c_str());
}

void FaultStage::pull(ReplayTime now) {
  if (!injector_) return;
  while (!released_.empty() && faulted_.size() < kLookaheadRecords &&
         faulted_bytes_ < kLookaheadBytes) {
    RxItem item = released_.front();  // a copy: pop_front counts its bytes
    released_.pop_front();
    const std::size_t before = faulted_.size();
    injector_->apply(std::move(item), faulted_, now);
    for (std::size_t i = before; i < faulted_.size(); ++i) {
      faulted_bytes_ += faulted_[i].item.payload().size();
    }
  }
}

void FaultStage::pop() {
  if (!injector_) {
    released_.pop_front();
    return;
  }
  faulted_bytes_ -= faulted_.front().item.payload().size();
  faulted_.pop_front();
}

const RxItem* FaultStage::loss(ReplayTime now) {
  while (injector_ && !faulted_.empty()) {
    const FaultedRx& front = faulted_.front();
    // A fault's loss says why in its data; a recorded one is the reader's.
    if (front.item.kind != RecordKind::device_lost || front.item.data.empty() ||
        front.item.due > now) {
      return nullptr;
    }
    if (!front.back_at || now < *front.back_at) return &front.item;
    pop();  // reconnected
  }
  return nullptr;
}

std::optional<FaultStage::Unread> FaultStage::unread() const {
  if (injector_ && injector_->injected() > 0) return std::nullopt;
  Unread unread;
  const auto count = [&unread](const RxItem& item) {
    if (item.kind != RecordKind::rx) return;
    unread.bytes += item.payload().size() - item.consumed;
    ++unread.records;
  };
  for (const FaultedRx& faulted : faulted_) count(faulted.item);
  for (const RxItem& item : released_.items()) count(item);
  return unread;
}

}  // namespace wiretape::detail
