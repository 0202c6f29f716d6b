// match=sequence: the session is one stream in recorded order. Two cursors
// stream it: the read cursor looks ahead (bounded) for the rx the client
// will read and releases each record once the client has written the tx
// bytes recorded before it; the write cursor follows the recorded tx and
// checks what the client writes (data, and under check=timing its timing and
// the recorded events).
#pragma once

#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "replay/exchanges.hpp"
#include "replay/profile.hpp"
#include "replay/response_fixer.hpp"
#include "replay/strategy.hpp"

namespace wiretape::detail {

class SequenceStrategy final : public ReplayStrategy {
 public:
  SequenceStrategy(const ReplayConfig& config, const ReplayTimeline& timeline,
                   ReleasedRx& released, MismatchReport& report,
                   const RecordSourceFactory& sources);

  void release(ReplayTime now) override;
  bool more_to_release() const override;
  // The end of a flush gate's flush_wait.
  std::optional<ReplayTime> wake() const override { return flush_gate_ends_; }
  void client_flushed() override;
  void write(const char* data, std::size_t size, ReplayTime now) override;
  void client_event(RecordKind kind,
                    const std::map<std::string, std::string>& fields) override;
  std::string unused_report(std::uint64_t queued_rx_bytes,
                            std::uint64_t queued_rx_records) override;

 private:
  // An rx record the read cursor looked ahead to, not yet entitled.
  struct Ahead {
    RxItem item;
    // Where the recorded tx was before it (tx_progress: bytes, or
    // datagrams), and the time of the last tx record before it (none:
    // before any write).
    std::uint64_t tx_before = 0;
    std::optional<std::uint64_t> anchor_t_ns;
    // Client flushes (flush_input, flush_output) recorded before it.
    std::uint64_t flushes_before = 0;
  };
  struct TxEnd {  // a recorded tx record the client finished writing
    std::uint64_t end_offset;  // in tx progress
    ReplayTime finished;
  };

  // With a profile (check=data or timing): the client's frames, compared by
  // key with the recorded ones, stand for the recorded frames' bytes.
  void write_frames(const char* data, std::size_t size, ReplayTime now);
  // A recorded request frame and where it is: the time of the record
  // holding its first byte, and its exchange (its index: with a profile an
  // exchange is one request frame, DESIGN.md section 13).
  struct RecordedFrame {
    Frame frame;
    std::uint64_t t_ns = 0;
    std::int64_t exchange = 0;
  };
  std::optional<RecordedFrame> next_recorded_frame();
  void fill();
  void entitle();
  std::optional<ReplayTime> finish_of(std::uint64_t tx_offset) const;
  bool next_tx_record();
  void write_records(const char* data, std::size_t size, ReplayTime now);
  // The recorded tx bytes the write cursor is at (those a mismatch report
  // says follow); empty at the end of the recorded writes.
  std::string_view recorded_writes_next() const;
  bool checks_events() const;
  // Whether the client's line changes (DTR, RTS, break) are checked: under
  // check=timing always, under check=data once the recording showed it
  // holds the device's lines (DESIGN.md section 20).
  bool checks_lines() const;
  // Recorded tx bytes the write cursor has passed (the client wrote them).
  std::uint64_t tx_consumed() const;
  // How far the recorded tx is, for what entitles rx: in bytes, or where
  // empty datagrams are records (replays_empty_datagrams) in datagrams, as
  // an empty request moves no byte. Of the read cursor; of the client.
  std::uint64_t rx_tx_progress() const;
  std::uint64_t tx_progress() const;

  const ReplayConfig& config_;
  const bool empty_datagrams_;  // replays_empty_datagrams(config_)
  const ReplayTimeline& timeline_;
  ReleasedRx& released_;
  MismatchReport& report_;

  // The read cursor.
  std::unique_ptr<RecordSource> rx_source_;
  bool rx_exhausted_ = false;
  std::uint64_t rx_tx_seen_ = 0;
  std::uint64_t rx_tx_datagrams_seen_ = 0;
  std::optional<std::uint64_t> rx_last_tx_t_ns_;
  std::uint64_t rx_flushes_seen_ = 0;
  // Whether the read cursor passed a modem_lines or line_break record: if
  // not, and it reached the end, the write cursor has no line change ahead.
  bool rx_line_records_seen_ = false;
  ModemInputs rx_device_lines_;  // as the read cursor's last line event left them
  ExchangeCursor rx_exchanges_;  // numbers what the read cursor reads
  std::uint64_t client_flushes_ = 0;  // the client made
  // Recorded client flushes the client did not make within flush_wait, or
  // wrote past: counted as made, so that later gates wait only for later
  // flushes.
  std::uint64_t flushes_forgiven_ = 0;
  void wrote_past_recorded_flushes();
  // When the front record, entitled but for a recorded flush, stops waiting
  // for it (none: no record waits for a flush).
  std::optional<ReplayTime> flush_gate_ends_;
  ReplayTime now_{};  // of the last release() or write()
  // Whether the front record waits for a flush alone (the client wrote what
  // the recording shows before it); sets flush_gate_ends_.
  bool held_by_flush_gate();
  ReplayTime due_of(const Ahead& ahead) const;
  std::deque<Ahead> ahead_;
  std::size_t ahead_bytes_ = 0;
  std::deque<TxEnd> tx_ends_;

  // The write cursor.
  std::unique_ptr<RecordSource> tx_source_;
  Record tx_record_;
  Wildcards tx_wildcards_;       // of tx_record_
  Wildcards pending_wildcards_;  // redaction events read before the next record
  bool have_tx_record_ = false;
  bool tx_exhausted_ = false;
  bool tx_hit_close_ = false;
  std::uint64_t tx_close_t_ns_ = 0;
  std::size_t tx_position_ = 0;
  ExchangeCursor tx_exchanges_;  // numbers what the write cursor reads
  std::int64_t tx_exchange_ = -1;  // of tx_record_; -1 before the first
  // Client flushes the write cursor passed; of them, those recorded before
  // tx_record_.
  std::uint64_t tx_flushes_seen_ = 0;
  std::uint64_t tx_record_flushes_before_ = 0;
  std::deque<Record> expected_events_;  // recorded before the next tx record
  bool lines_recorded_ = false;  // the write cursor passed a record of the device's lines
  std::optional<ReplayTime> previous_tx_finished_;
  std::uint64_t previous_tx_t_ns_ = 0;
  std::uint64_t tx_written_ = 0;  // bytes the client wrote
  std::uint64_t tx_datagrams_written_ = 0;  // recorded tx datagrams the client wrote
  std::uint64_t tx_recorded_done_ = 0;  // of the tx records written in full

  // With a profile: the recorded tx stream framed (its own cursor), and the
  // client's.
  std::unique_ptr<RecordSource> frame_source_;
  std::unique_ptr<TimedFramer> recorded_framer_;
  std::unique_ptr<Framer> client_framer_;
  std::deque<RecordedFrame> recorded_frames_;
  std::int64_t recorded_frames_seen_ = 0;
  std::vector<TimedFramer::TimedFrame> scratch_frames_;
  bool frame_source_done_ = false;
  // With a profile that fixes responses: entitled rx passes through it.
  std::unique_ptr<ResponseFixer> fixer_;
  void release_item(RxItem&& item, std::uint64_t tx_before);
  void release_fixed();
};

}  // namespace wiretape::detail
