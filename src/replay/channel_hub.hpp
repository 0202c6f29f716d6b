// What the replays of one session file's channels share within a process
// (DESIGN.md section 19): one clock, and under timing=causal the order across
// channels (rx on one channel waits for the client's tx that preceded it on
// the others). Found by the file's device and inode, so that two names of
// one file (a link) share too.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "replay/timing.hpp"

namespace wiretape::detail {

class ChannelMember;

class ChannelHub : public std::enable_shared_from_this<ChannelHub> {
 public:
  // The hub of the session file at `path` in this process: made by the first
  // replay of it that asks, shared while one lives.
  static std::shared_ptr<ChannelHub> of_file(const std::string& path);

  // The file's clock: the time of the first call, for every call after it.
  // `open_time` for ports as they open; `first_client_time` for the first
  // client session of virtual devices (a bridge's port opens before its
  // client comes).
  ReplayTime open_time(ReplayTime now);
  ReplayTime first_client_time(ReplayTime now);

  // A client's tx recorded on a channel: where its bytes end (counted over
  // the channel's tx) and when it was recorded.
  struct TxMark {
    std::uint64_t end_offset = 0;
    std::uint64_t t_ns = 0;
  };
  // Joins the causal order across channels as a replay of channel
  // `channel`, whose recorded tx are `marks` (in order).
  std::shared_ptr<ChannelMember> join(std::uint16_t channel, std::vector<TxMark> marks);

 private:
  friend class ChannelMember;
  struct Progress;

  ChannelHub() = default;

  // Under mutex_.
  std::optional<ReplayTime> clock_;
  std::optional<ReplayTime> client_clock_;
  std::vector<ChannelMember*> members_;
  std::mutex mutex_;
  // Held while a member's waker runs and while one leaves: a member that
  // left is never woken after.
  std::mutex wake_mutex_;
};

// One replay's place in its file's causal order across channels.
class ChannelMember {
 public:
  ChannelMember(std::shared_ptr<ChannelHub> hub, std::uint16_t channel,
                std::vector<ChannelHub::TxMark> marks);
  ~ChannelMember();
  ChannelMember(const ChannelMember&) = delete;
  ChannelMember& operator=(const ChannelMember&) = delete;

  // Whether rx recorded at `t_ns` on this channel may be released: the
  // client has written, on every other channel of the file replayed in this
  // process, all the tx recorded there before `t_ns`. `anchor` is the latest
  // of those writes (nullopt: none preceded it).
  struct Gate {
    bool open = true;
    std::optional<ReplayTimeline::Anchor> anchor;
  };
  Gate gate(std::uint64_t t_ns) const;

  // The client wrote `size` bytes on this channel, finished at `now`: the
  // replays of the other channels are woken.
  void wrote(std::size_t size, ReplayTime now);

  // Called (without this member's replay's lock) when another channel's
  // write may have released something here; empty: nobody.
  void set_waker(std::function<void()> waker);
  // Leaves the order: a closed replay no longer holds the others back.
  void leave();

 private:
  friend class ChannelHub;

  const std::shared_ptr<ChannelHub> hub_;
  const std::uint16_t channel_;
  // Under hub_->mutex_.
  const std::vector<ChannelHub::TxMark> marks_;
  std::vector<ReplayTime> covered_;  // when the client's writes covered marks_[i]
  std::uint64_t written_ = 0;
  bool joined_ = true;
  // Under hub_->wake_mutex_.
  std::function<void()> waker_;
};

}  // namespace wiretape::detail
