#include "replay/channel_hub.hpp"

#include <sys/stat.h>

#include <algorithm>
#include <map>

#include "posix/syscalls.hpp"

namespace wiretape::detail {

std::shared_ptr<ChannelHub> ChannelHub::of_file(const std::string& path) {
  struct stat status {};
  if (sys::stat(path.c_str(), &status) != 0) {
    // Unreachable in practice (the replay has just opened it): a hub of its
    // own, shared with nobody.
    return std::shared_ptr<ChannelHub>(new ChannelHub());
  }
  static std::mutex registry_mutex;
  static std::map<std::pair<dev_t, ino_t>, std::weak_ptr<ChannelHub>> registry;
  std::lock_guard<std::mutex> lock(registry_mutex);
  // Hubs of files nobody replays any more are forgotten as others come.
  for (auto it = registry.begin(); it != registry.end();) {
    it = it->second.expired() ? registry.erase(it) : std::next(it);
  }
  std::weak_ptr<ChannelHub>& slot = registry[{status.st_dev, status.st_ino}];
  if (std::shared_ptr<ChannelHub> hub = slot.lock()) return hub;
  std::shared_ptr<ChannelHub> hub(new ChannelHub());
  slot = hub;
  return hub;
}

ReplayTime ChannelHub::open_time(ReplayTime now) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!clock_) clock_ = now;
  return *clock_;
}

ReplayTime ChannelHub::first_client_time(ReplayTime now) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!client_clock_) client_clock_ = now;
  return *client_clock_;
}

std::shared_ptr<ChannelMember> ChannelHub::join(std::uint16_t channel,
                                                std::vector<TxMark> marks) {
  auto member = std::make_shared<ChannelMember>(shared_from_this(), channel, std::move(marks));
  std::lock_guard<std::mutex> lock(mutex_);
  members_.push_back(member.get());
  return member;
}

ChannelMember::ChannelMember(std::shared_ptr<ChannelHub> hub, std::uint16_t channel,
                             std::vector<ChannelHub::TxMark> marks)
    : hub_(std::move(hub)), channel_(channel), marks_(std::move(marks)) {
  covered_.reserve(marks_.size());
}

ChannelMember::~ChannelMember() { leave(); }

void ChannelMember::leave() {
  std::lock_guard<std::mutex> wake_lock(hub_->wake_mutex_);
  waker_ = nullptr;
  std::lock_guard<std::mutex> lock(hub_->mutex_);
  if (!joined_) return;
  joined_ = false;
  auto& members = hub_->members_;
  members.erase(std::remove(members.begin(), members.end(), this), members.end());
}

ChannelMember::Gate ChannelMember::gate(std::uint64_t t_ns) const {
  Gate gate;
  std::lock_guard<std::mutex> lock(hub_->mutex_);
  for (const ChannelMember* other : hub_->members_) {
    if (other == this || other->channel_ == channel_) continue;
    // The other channel's tx recorded before t_ns.
    const auto before = std::lower_bound(
        other->marks_.begin(), other->marks_.end(), t_ns,
        [](const ChannelHub::TxMark& mark, std::uint64_t t) { return mark.t_ns < t; });
    if (before == other->marks_.begin()) continue;
    const std::size_t last = static_cast<std::size_t>(before - other->marks_.begin()) - 1;
    if (last >= other->covered_.size()) return Gate{false, std::nullopt};
    const ReplayTimeline::Anchor anchor{other->covered_[last], other->marks_[last].t_ns};
    if (!gate.anchor || anchor.finished > gate.anchor->finished) gate.anchor = anchor;
  }
  return gate;
}

void ChannelMember::wrote(std::size_t size, ReplayTime now) {
  if (size == 0) return;
  {
    std::lock_guard<std::mutex> lock(hub_->mutex_);
    written_ += size;
    const std::size_t before = covered_.size();
    while (covered_.size() < marks_.size() && marks_[covered_.size()].end_offset <= written_) {
      covered_.push_back(now);
    }
    if (covered_.size() == before) return;  // nothing newly covered: nobody to wake
  }
  std::lock_guard<std::mutex> wake_lock(hub_->wake_mutex_);
  std::vector<ChannelMember*> others;
  {
    std::lock_guard<std::mutex> lock(hub_->mutex_);
    others = hub_->members_;
  }
  for (ChannelMember* other : others) {
    if (other != this && other->waker_) other->waker_();
  }
}

void ChannelMember::set_waker(std::function<void()> waker) {
  std::lock_guard<std::mutex> wake_lock(hub_->wake_mutex_);
  waker_ = std::move(waker);
}

}  // namespace wiretape::detail
