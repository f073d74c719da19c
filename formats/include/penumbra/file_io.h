// Files read and written in pieces, for the importers, the model writer and
// the streamed (out-of-core) preprocessor: an atomic writer (temporary name,
// then rename), a buffered reader that reads with pread (nothing mapped), and
// anonymous temporary files. Every failure throws Error naming the path.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace penumbra {

// Files to remove if the process is interrupted. Once removeTemporariesOnSignals()
// has installed its handlers (the command-line tools do; a library user
// decides), SIGINT, SIGTERM and SIGHUP remove every tracked file, print one
// line "<program>: interrupted (<signal>); its temporary files removed" and end
// the process by the same signal. trackTemporary returns a slot for
// untrackTemporary, or -1 when the path is not tracked (longer than 1023
// bytes, or 1024 tracked already: such a file is left to the next run's sweep).
int trackTemporary(const std::string& path);
void untrackTemporary(int slot);
void removeTemporariesOnSignals(const char* program);

// trackTemporary for a scope.
class TrackedTemporary {
  public:
    explicit TrackedTemporary(const std::string& path) : slot_(trackTemporary(path)) {}
    ~TrackedTemporary() { untrackTemporary(slot_); }
    TrackedTemporary(const TrackedTemporary&) = delete;
    TrackedTemporary& operator=(const TrackedTemporary&) = delete;

  private:
    int slot_;
};

// Removes "<path>.tmp-<pid>" files left by processes that no longer run (a
// writer killed before it could clean up); those of live processes stay.
// Process ids are this machine's (this container's): two machines or
// containers writing the same output path in a shared folder at the same time
// may remove each other's temporary file, and one of them then fails with a
// one-line rename error.
void removeStaleTemporaries(const std::string& path);
// Whether no process of this machine has id `pid` (another process's leftover
// temporary file may go); false for this process and for pid <= 0.
bool processIsGone(long pid);

// Buffered writer to "<path>.tmp-<pid>"; commit() flushes, closes and renames
// it over path. Destroying an uncommitted writer removes the temporary file,
// so an interrupted write never leaves a file under `path`. Opening one
// removes the temporary files of earlier writers of `path` that were killed.
class AtomicFileWriter {
  public:
    explicit AtomicFileWriter(const std::string& path);
    ~AtomicFileWriter();
    AtomicFileWriter(const AtomicFileWriter&) = delete;
    AtomicFileWriter& operator=(const AtomicFileWriter&) = delete;

    void write(const void* data, size_t size);
    void write(std::string_view text) { write(text.data(), text.size()); }
    // Overwrites bytes already written (e.g. a header whose checksums are known
    // only at the end); [offset, offset + size) must lie before written().
    void writeAt(uint64_t offset, const void* data, size_t size);
    // Bytes written so far (buffered or not).
    uint64_t written() const { return flushed_ + used_; }
    // Returns space for at least `size` bytes (size <= kBufferSize); finish
    // with advance(bytesUsed).
    char* reserve(size_t size)
    {
        if (used_ + size > buffer_.size())
            flush();
        return buffer_.data() + used_;
    }
    void advance(size_t size) { used_ += size; }
    // Durability::Synced also fsyncs the file before the rename and its folder
    // after it, so a crash never leaves a renamed file whose data is not on disk.
    enum class Durability { Buffered, Synced };
    void commit(Durability durability = Durability::Buffered);
    const std::string& path() const { return path_; }

    static constexpr size_t kBufferSize = size_t(4) << 20;

  private:
    void flush();

    std::string path_;
    std::string tempPath_;
    int fd_ = -1;
    std::vector<char> buffer_;
    size_t used_ = 0;
    uint64_t flushed_ = 0;
    bool committed_ = false;
    int tracked_ = -1; // trackTemporary's slot of tempPath_
};

// Sequential reads of a file through a buffer filled with pread (the file is
// never mapped, so memory stays at the buffer whatever the file's size), plus
// random reads. Throws Error("<path>: file not found" / "not a regular file" /
// "cannot open: ..." / "read failed: ...").
class FileReader {
  public:
    explicit FileReader(const std::string& path, size_t bufferBytes = size_t(4) << 20);
    ~FileReader();
    FileReader(const FileReader&) = delete;
    FileReader& operator=(const FileReader&) = delete;

    const std::string& path() const { return path_; }
    uint64_t size() const { return size_; }
    // Position of data()[0] in the file.
    uint64_t offset() const { return bufferOffset_ + position_; }
    void seek(uint64_t offset);
    // Makes at least n bytes (n <= the buffer size) available at data(); false
    // when the file ends first (then available() tells how many there are).
    bool ensure(size_t n);
    const uint8_t* data() const { return buffer_.data() + position_; }
    size_t available() const { return filled_ - position_; }
    void advance(size_t n) { position_ += n; }
    size_t bufferSize() const { return buffer_.size(); }
    // Reads exactly size bytes at offset (independent of the sequential position).
    void readAt(uint64_t offset, void* out, size_t size) const;

  private:
    std::string path_;
    int fd_ = -1;
    uint64_t size_ = 0;
    std::vector<uint8_t> buffer_;
    uint64_t bufferOffset_ = 0; // file offset of buffer_[0]
    size_t position_ = 0, filled_ = 0;
};

// An anonymous temporary file in `directory` (unlinked at once, so nothing is
// left behind by a crash): appended through a buffer, read at any offset.
class TemporaryFile {
  public:
    TemporaryFile(const std::string& directory, const std::string& purpose, size_t bufferBytes = size_t(1) << 20);
    ~TemporaryFile();
    TemporaryFile(const TemporaryFile&) = delete;
    TemporaryFile& operator=(const TemporaryFile&) = delete;

    void append(const void* data, size_t size);
    // Makes every appended byte readable (flushes the buffer).
    void flush();
    uint64_t size() const { return flushed_ + used_; }
    // Reads exactly size bytes at offset; flushes first if they are still buffered.
    void readAt(uint64_t offset, void* out, size_t size);
    // Releases the buffer (nothing more will be appended).
    void finish();
    const std::string& name() const { return name_; }

  private:
    std::string name_;
    int fd_ = -1;
    std::vector<uint8_t> buffer_;
    size_t used_ = 0;
    uint64_t flushed_ = 0;
};

// Reads exactly size bytes at offset of an open descriptor (EINTR and short
// reads retried); throws Error("<name>: read failed ..." / "truncated ...").
void readExactly(int fd, uint64_t offset, void* out, size_t size, const std::string& name);

} // namespace penumbra
