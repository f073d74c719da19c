// Format dispatch, memory-mapped input, atomic (temp file + rename) output and
// the checks every importer's result passes through.
#include "penumbra/io.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>

#include "io_internal.h"

namespace penumbra {
namespace detail {

MappedFile::MappedFile(const std::string& path)
{
    int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
        int err = errno;
        if (err == ENOENT)
            fail(path, "file not found");
        fail(path, std::string("cannot open: ") + std::strerror(err));
    }
    struct stat st {};
    if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
        ::close(fd);
        fail(path, "not a regular file");
    }
    size_ = size_t(st.st_size);
    if (size_ == 0) {
        ::close(fd);
        fail(path, "empty file");
    }
    void* mapped = ::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE | MAP_POPULATE, fd, 0);
    int err = errno;
    ::close(fd);
    if (mapped == MAP_FAILED)
        fail(path, std::string("cannot map file: ") + std::strerror(err));
    data_ = static_cast<const uint8_t*>(mapped);
    mapped_ = true;
}

MappedFile::MappedFile(const std::string& path, const uint8_t* data, size_t size) : data_(data), size_(size)
{
    if (size_ == 0)
        fail(path, "empty file");
}

void MappedFile::release() const
{
    if (mapped_)
        ::madvise(const_cast<uint8_t*>(data_), size_, MADV_DONTNEED);
}

MappedFile::~MappedFile()
{
    if (mapped_)
        ::munmap(const_cast<uint8_t*>(data_), size_);
}

namespace {
struct PendingWarning {
    std::string kind, message;
};
// The warnings of the importScene call running on this thread (null outside one).
thread_local std::vector<PendingWarning>* pendingWarnings = nullptr;
} // namespace

void importWarning(const std::string& path, const std::string& kind, const std::string& message)
{
    if (!pendingWarnings) {
        warn(path, message);
        return;
    }
    for (const PendingWarning& pending : *pendingWarnings)
        if (pending.kind == kind)
            return;
    pendingWarnings->push_back({kind, message});
}

std::string quoteToken(std::string_view token)
{
    std::string out = "'";
    for (size_t i = 0; i < token.size() && i < 40; ++i) {
        unsigned char c = static_cast<unsigned char>(token[i]);
        out += (c >= 32 && c < 127) ? char(c) : '?';
    }
    if (token.size() > 40)
        out += "...";
    return out + "'";
}

void validateMesh(const std::string& path, const Mesh& mesh)
{
    if (mesh.positions.size() % 3 != 0 || mesh.indices.size() % 3 != 0)
        fail(path, "internal error: ragged position or index array");
    if (mesh.vertexCount() > std::numeric_limits<uint32_t>::max())
        fail(path, "too many vertices (" + std::to_string(mesh.vertexCount()) + ", limit 4294967295)");
    const float* p = mesh.positions.data();
    const size_t floatCount = mesh.positions.size();
    for (size_t i = 0; i < floatCount; ++i) {
        if (!std::isfinite(p[i])) {
            size_t v = i / 3;
            char text[160];
            std::snprintf(text, sizeof(text), "vertex %zu has a non-finite position (%g, %g, %g)", v, double(p[v * 3]),
                          double(p[v * 3 + 1]), double(p[v * 3 + 2]));
            fail(path, text);
        }
    }
    const uint32_t vertexCount = uint32_t(mesh.vertexCount());
    const uint32_t* idx = mesh.indices.data();
    const size_t indexCount = mesh.indices.size();
    uint32_t maxIndex = 0;
    for (size_t i = 0; i < indexCount; ++i)
        maxIndex = std::max(maxIndex, idx[i]);
    if (indexCount > 0 && maxIndex >= vertexCount) {
        for (size_t i = 0; i < indexCount; ++i)
            if (idx[i] >= vertexCount)
                fail(path, "triangle " + std::to_string(i / 3) + " references vertex " + std::to_string(idx[i]) +
                               " but there are " + std::to_string(vertexCount) + " vertices");
    }
    // Colours: importers clamp them to [0, 1]; these are the invariants the preprocessor relies on.
    if (!mesh.colors.empty() && mesh.colors.size() != mesh.positions.size())
        fail(path, "internal error: " + std::to_string(mesh.colors.size() / 3) + " vertex colours for " +
                       std::to_string(vertexCount) + " vertices");
    for (float c : mesh.colors)
        if (!(c >= 0.0f && c <= 1.0f))
            fail(path, "vertex colour component " + std::to_string(c) + " is outside [0, 1]");
    for (const Material& material : mesh.materials)
        for (int k = 0; k < 4; ++k)
            if (!(material.baseColor[k] >= 0.0f && material.baseColor[k] <= 1.0f))
                fail(path, "material '" + material.name + "' has a base colour component outside [0, 1]");
    if (!mesh.triangleMaterials.empty()) {
        if (mesh.triangleMaterials.size() != mesh.triangleCount())
            fail(path, "internal error: " + std::to_string(mesh.triangleMaterials.size()) + " triangle materials for " +
                           std::to_string(mesh.triangleCount()) + " triangles");
        for (size_t t = 0; t < mesh.triangleMaterials.size(); ++t)
            if (mesh.triangleMaterials[t] >= mesh.materials.size())
                fail(path, "triangle " + std::to_string(t) + " names material " + std::to_string(mesh.triangleMaterials[t]) +
                               " but there are " + std::to_string(mesh.materials.size()));
    }
}

void weldTriangles(const std::vector<float>& corners, Mesh& mesh)
{
    const size_t cornerCount = corners.size() / 3;
    size_t tableSize = 16;
    while (tableSize < cornerCount * 2)
        tableSize <<= 1;
    std::vector<uint32_t> table(tableSize, UINT32_MAX);
    mesh.positions.clear();
    mesh.positions.reserve(corners.size());
    mesh.indices.resize(cornerCount);
    auto key = [](float f) {
        uint32_t bits;
        std::memcpy(&bits, &f, 4);
        return bits == 0x80000000u ? 0u : bits;
    };
    for (size_t c = 0; c < cornerCount; ++c) {
        const float* p = &corners[c * 3];
        uint32_t kx = key(p[0]), ky = key(p[1]), kz = key(p[2]);
        uint64_t h = (uint64_t(kx) * 0x9E3779B97F4A7C15ull) ^ (uint64_t(ky) * 0xC2B2AE3D27D4EB4Full) ^
                     (uint64_t(kz) * 0x165667B19E3779F9ull);
        h ^= h >> 29;
        size_t slot = size_t(h) & (tableSize - 1);
        for (;;) {
            uint32_t v = table[slot];
            if (v == UINT32_MAX) {
                v = uint32_t(mesh.positions.size() / 3);
                table[slot] = v;
                mesh.positions.insert(mesh.positions.end(), p, p + 3);
                mesh.indices[c] = v;
                break;
            }
            const float* q = &mesh.positions[size_t(v) * 3];
            if (key(q[0]) == kx && key(q[1]) == ky && key(q[2]) == kz) {
                mesh.indices[c] = v;
                break;
            }
            slot = (slot + 1) & (tableSize - 1);
        }
    }
    mesh.positions.shrink_to_fit();
}

} // namespace detail

namespace {

std::string lowerExtension(const std::string& path)
{
    size_t slash = path.find_last_of('/');
    size_t dot = path.find_last_of('.');
    if (dot == std::string::npos || (slash != std::string::npos && dot < slash))
        return {};
    std::string ext = path.substr(dot + 1);
    for (char& c : ext)
        c = char(std::tolower(static_cast<unsigned char>(c)));
    return ext;
}

} // namespace

ModelFormat formatFromPath(const std::string& path)
{
    std::string ext = lowerExtension(path);
    if (ext == "obj")
        return ModelFormat::Obj;
    if (ext == "ply")
        return ModelFormat::Ply;
    if (ext == "stl")
        return ModelFormat::Stl;
    if (ext == "gltf")
        return ModelFormat::Gltf;
    if (ext == "glb")
        return ModelFormat::Glb;
    if (ext == "drc")
        return ModelFormat::Draco;
    fail(path, ext.empty() ? "unknown model format (no file extension; expected .obj, .ply, .stl, .gltf, .glb or .drc)"
                           : "unknown model format '." + ext + "' (expected .obj, .ply, .stl, .gltf, .glb or .drc)");
}

namespace {

std::atomic<WarningSink> warningSink{nullptr};

Scene importFile(const std::string& path, ModelFormat format, const detail::MappedFile& file)
{
    std::vector<detail::PendingWarning> warnings;
    struct Scope {
        std::vector<detail::PendingWarning>* previous;
        ~Scope() { detail::pendingWarnings = previous; }
    } scope{detail::pendingWarnings};
    detail::pendingWarnings = &warnings;
    Scene scene;
    switch (format) {
    case ModelFormat::Obj:
        scene = detail::importObj(path, file);
        break;
    case ModelFormat::Ply:
        scene = detail::importPly(path, file);
        break;
    case ModelFormat::Stl:
        scene = detail::importStl(path, file);
        break;
    case ModelFormat::Gltf:
        scene = detail::importGltf(path, file, false);
        break;
    case ModelFormat::Glb:
        scene = detail::importGltf(path, file, true);
        break;
    case ModelFormat::Draco:
        scene = detail::importDraco(path, file);
        break;
    }
    if (scene.mesh.triangleCount() == 0)
        fail(path, "no triangles");
    detail::validateMesh(path, scene.mesh);
    for (const detail::PendingWarning& warning : warnings)
        warn(path, warning.message);
    return scene;
}

} // namespace

WarningSink setWarningSink(WarningSink sink)
{
    return warningSink.exchange(sink);
}

void warn(const std::string& subject, const std::string& problem)
{
    std::string line = subject + ": " + problem;
    if (WarningSink sink = warningSink.load())
        sink(line);
    else
        std::fprintf(stderr, "penumbra: warning: %s\n", line.c_str());
}

Scene importScene(const std::string& path)
{
    ModelFormat format = formatFromPath(path);
    detail::MappedFile file(path);
    return importFile(path, format, file);
}

Scene importSceneMemory(std::span<const uint8_t> bytes, const std::string& name)
{
    ModelFormat format = formatFromPath(name);
    detail::MappedFile file(name, bytes.data(), bytes.size());
    return importFile(name, format, file);
}

void exportScene(const Scene& scene, const std::string& path, const ExportOptions& options)
{
    ModelFormat format = formatFromPath(path);
    if (scene.mesh.triangleCount() == 0)
        fail(path, "nothing to export: the mesh has no triangles");
    detail::validateMesh(path, scene.mesh);
    if (options.dracoPositionBits < 1 || options.dracoPositionBits > 30)
        fail(path, "Draco position quantization must be 1..30 bits, not " + std::to_string(options.dracoPositionBits));
    detail::AtomicFileWriter out(path);
    switch (format) {
    case ModelFormat::Obj:
        detail::exportObj(scene, out);
        break;
    case ModelFormat::Ply:
        detail::exportPly(scene, out, options.binary);
        break;
    case ModelFormat::Stl:
        detail::exportStl(scene, out, options.binary);
        break;
    case ModelFormat::Gltf:
        detail::exportGltf(scene, path, out, false, options);
        break;
    case ModelFormat::Glb:
        detail::exportGltf(scene, path, out, true, options);
        break;
    case ModelFormat::Draco:
        detail::exportDraco(scene, path, out, options);
        break;
    }
    out.commit();
}

namespace {

// trackTemporary's table: fixed storage, read by the signal handler without
// locks. A slot's state is published after its path is written, and its
// version is odd while the path is rewritten (a seqlock): the handler removes
// a path only if the version it read before copying it is even and unchanged
// after, so a slot freed and reused by another thread meanwhile is skipped.
constexpr int kTrackedSlots = 1024;
constexpr size_t kTrackedPathBytes = 1024;
struct TrackedSlot {
    std::atomic<int> state{0}; // 0 free, 1 being written, 2 holds a path
    std::atomic<uint32_t> version{0};
    char path[kTrackedPathBytes];
};
TrackedSlot gTracked[kTrackedSlots];
const char* gSignalProgram = "penumbra";

void writeAll(int fd, const char* text)
{
    size_t size = std::strlen(text);
    while (size > 0) {
        const ssize_t n = ::write(fd, text, size);
        if (n <= 0)
            return;
        text += n;
        size -= size_t(n);
    }
}

extern "C" void removeTrackedAndExit(int signalNumber)
{
    const int savedErrno = errno;
    char path[kTrackedPathBytes];
    for (TrackedSlot& slot : gTracked) {
        const uint32_t version = slot.version.load(std::memory_order_acquire);
        if ((version & 1u) != 0 || slot.state.load(std::memory_order_acquire) != 2)
            continue;
        std::memcpy(path, slot.path, kTrackedPathBytes);
        path[kTrackedPathBytes - 1] = '\0';
        // A read-modify-write with release order: the copy above cannot move after it.
        if (slot.version.fetch_add(0, std::memory_order_acq_rel) == version)
            ::unlink(path);
    }
    const char* name = signalNumber == SIGINT ? "SIGINT" : signalNumber == SIGTERM ? "SIGTERM" : "SIGHUP";
    writeAll(2, gSignalProgram);
    writeAll(2, ": interrupted (");
    writeAll(2, name);
    writeAll(2, "); its temporary files removed\n");
    // End by the signal here: its default action, unblocked, then raised (the handler never returns).
    struct sigaction defaultAction {};
    defaultAction.sa_handler = SIG_DFL;
    sigemptyset(&defaultAction.sa_mask);
    ::sigaction(signalNumber, &defaultAction, nullptr);
    sigset_t unblock;
    sigemptyset(&unblock);
    sigaddset(&unblock, signalNumber);
    ::pthread_sigmask(SIG_UNBLOCK, &unblock, nullptr);
    ::raise(signalNumber);
    errno = savedErrno; // reached only if the default action does not end the process
}

} // namespace

int trackTemporary(const std::string& path)
{
    if (path.size() >= kTrackedPathBytes)
        return -1;
    for (int i = 0; i < kTrackedSlots; ++i) {
        int expected = 0;
        if (gTracked[i].state.compare_exchange_strong(expected, 1, std::memory_order_acquire)) {
            gTracked[i].version.fetch_add(1, std::memory_order_acq_rel); // odd: being rewritten
            std::memcpy(gTracked[i].path, path.c_str(), path.size() + 1);
            gTracked[i].version.fetch_add(1, std::memory_order_release);
            gTracked[i].state.store(2, std::memory_order_release);
            return i;
        }
    }
    return -1;
}

void untrackTemporary(int slot)
{
    if (slot >= 0 && slot < kTrackedSlots)
        gTracked[slot].state.store(0, std::memory_order_release);
}

void removeTemporariesOnSignals(const char* program)
{
    gSignalProgram = program;
    struct sigaction action {};
    action.sa_handler = removeTrackedAndExit;
    sigemptyset(&action.sa_mask);
    action.sa_flags = 0;
    for (int signalNumber : {SIGINT, SIGTERM, SIGHUP}) {
        struct sigaction previous {};
        // A signal the caller's parent ignores (nohup's SIGHUP) stays ignored.
        if (::sigaction(signalNumber, nullptr, &previous) == 0 && previous.sa_handler == SIG_IGN)
            continue;
        ::sigaction(signalNumber, &action, nullptr);
    }
}

void removeStaleTemporaries(const std::string& path)
{
    const std::filesystem::path target(path);
    const std::string prefix = target.filename().string() + ".tmp-";
    std::filesystem::path folder = target.parent_path();
    if (folder.empty())
        folder = ".";
    std::error_code error;
    for (std::filesystem::directory_iterator it(folder, error), end; !error && it != end; it.increment(error)) {
        const std::string file = it->path().filename().string();
        if (file.size() <= prefix.size() || file.compare(0, prefix.size(), prefix) != 0)
            continue;
        const std::string digits = file.substr(prefix.size());
        if (digits.size() > 9 || digits.find_first_not_of("0123456789") != std::string::npos)
            continue; // not ours: only "<name>.tmp-<pid>" is
        if (processIsGone(std::strtol(digits.c_str(), nullptr, 10))) {
            std::error_code ignored;
            std::filesystem::remove(it->path(), ignored);
        }
    }
}

bool processIsGone(long pid)
{
    return pid > 0 && pid != ::getpid() && ::kill(pid_t(pid), 0) != 0 && errno == ESRCH;
}

AtomicFileWriter::AtomicFileWriter(const std::string& path)
    : path_(path), tempPath_(path + ".tmp-" + std::to_string(::getpid())), buffer_(kBufferSize)
{
    removeStaleTemporaries(path);
    tracked_ = trackTemporary(tempPath_);
    fd_ = ::open(tempPath_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd_ < 0) {
        untrackTemporary(tracked_);
        fail(path_, std::string("cannot create '") + tempPath_ + "': " + std::strerror(errno));
    }
}

AtomicFileWriter::~AtomicFileWriter()
{
    if (fd_ >= 0)
        ::close(fd_);
    if (!committed_)
        ::unlink(tempPath_.c_str());
    untrackTemporary(tracked_);
}

void AtomicFileWriter::flush()
{
    size_t done = 0;
    while (done < used_) {
        ssize_t n = ::write(fd_, buffer_.data() + done, used_ - done);
        if (n < 0 && errno == EINTR)
            continue;
        if (n <= 0)
            fail(path_, std::string("write failed: ") + std::strerror(errno));
        done += size_t(n);
    }
    flushed_ += used_;
    used_ = 0;
}

void AtomicFileWriter::writeAt(uint64_t offset, const void* data, size_t size)
{
    if (offset > written() || size > written() - offset)
        fail(path_, "internal error: writeAt past the end of the written bytes");
    flush();
    const char* bytes = static_cast<const char*>(data);
    size_t done = 0;
    while (done < size) {
        ssize_t n = ::pwrite(fd_, bytes + done, size - done, off_t(offset + done));
        if (n < 0 && errno == EINTR)
            continue;
        if (n <= 0)
            fail(path_, std::string("write failed: ") + std::strerror(errno));
        done += size_t(n);
    }
}

void AtomicFileWriter::write(const void* data, size_t size)
{
    const char* bytes = static_cast<const char*>(data);
    if (used_ + size <= buffer_.size()) {
        std::memcpy(buffer_.data() + used_, bytes, size);
        used_ += size;
        return;
    }
    flush();
    if (size < buffer_.size()) {
        std::memcpy(buffer_.data(), bytes, size);
        used_ = size;
        return;
    }
    // Large block: write straight from the caller's memory.
    size_t done = 0;
    while (done < size) {
        ssize_t n = ::write(fd_, bytes + done, std::min<size_t>(size - done, size_t(1) << 30));
        if (n < 0 && errno == EINTR)
            continue;
        if (n <= 0)
            fail(path_, std::string("write failed: ") + std::strerror(errno));
        done += size_t(n);
    }
    flushed_ += size;
}

void AtomicFileWriter::commit(Durability durability)
{
    flush();
    if (durability == Durability::Synced && ::fsync(fd_) != 0)
        fail(path_, std::string("fsync failed: ") + std::strerror(errno));
    int fd = fd_;
    fd_ = -1;
    if (::close(fd) != 0)
        fail(path_, std::string("write failed: ") + std::strerror(errno));
    if (std::rename(tempPath_.c_str(), path_.c_str()) != 0)
        fail(path_, std::string("cannot rename temporary file: ") + std::strerror(errno));
    committed_ = true;
    untrackTemporary(tracked_);
    tracked_ = -1;
    if (durability == Durability::Synced) {
        // The rename itself is durable once the folder's entry is.
        size_t slash = path_.find_last_of('/');
        std::string folder = slash == std::string::npos ? "." : slash == 0 ? "/" : path_.substr(0, slash);
        int dir = ::open(folder.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
        if (dir >= 0) {
            ::fsync(dir);
            ::close(dir);
        }
    }
}


void readExactly(int fd, uint64_t offset, void* out, size_t size, const std::string& name)
{
    uint8_t* bytes = static_cast<uint8_t*>(out);
    size_t done = 0;
    while (done < size) {
        ssize_t n = ::pread(fd, bytes + done, std::min<size_t>(size - done, size_t(1) << 30), off_t(offset + done));
        if (n < 0 && errno == EINTR)
            continue;
        if (n < 0)
            fail(name, std::string("read failed: ") + std::strerror(errno));
        if (n == 0)
            fail(name, "truncated: the file ends at byte " + std::to_string(offset + done) + " (it changed while it was read?)");
        done += size_t(n);
    }
}

FileReader::FileReader(const std::string& path, size_t bufferBytes) : path_(path)
{
    fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd_ < 0) {
        int err = errno;
        if (err == ENOENT)
            fail(path, "file not found");
        fail(path, std::string("cannot open: ") + std::strerror(err));
    }
    struct stat st {};
    if (::fstat(fd_, &st) != 0 || !S_ISREG(st.st_mode)) {
        ::close(fd_);
        fd_ = -1;
        fail(path, "not a regular file");
    }
    size_ = uint64_t(st.st_size);
    buffer_.resize(std::max<size_t>(bufferBytes, 4096));
#ifdef POSIX_FADV_SEQUENTIAL
    ::posix_fadvise(fd_, 0, 0, POSIX_FADV_SEQUENTIAL);
#endif
}

FileReader::~FileReader()
{
    if (fd_ >= 0)
        ::close(fd_);
}

void FileReader::seek(uint64_t offset)
{
    if (offset >= bufferOffset_ && offset <= bufferOffset_ + filled_) {
        position_ = size_t(offset - bufferOffset_);
        return;
    }
    bufferOffset_ = offset;
    position_ = filled_ = 0;
}

bool FileReader::ensure(size_t n)
{
    if (filled_ - position_ >= n)
        return true;
    if (n > buffer_.size())
        fail(path_, "internal error: a read of " + std::to_string(n) + " bytes does not fit the buffer");
    // Keep the unread bytes, then fill the rest of the buffer.
    const size_t keep = filled_ - position_;
    std::memmove(buffer_.data(), buffer_.data() + position_, keep);
    bufferOffset_ += position_;
    position_ = 0;
    filled_ = keep;
    while (filled_ < buffer_.size() && bufferOffset_ + filled_ < size_) {
        const size_t want = size_t(std::min<uint64_t>(buffer_.size() - filled_, size_ - bufferOffset_ - filled_));
        ssize_t got = ::pread(fd_, buffer_.data() + filled_, want, off_t(bufferOffset_ + filled_));
        if (got < 0 && errno == EINTR)
            continue;
        if (got < 0)
            fail(path_, std::string("read failed: ") + std::strerror(errno));
        if (got == 0)
            break; // the file shrank
        filled_ += size_t(got);
        if (filled_ >= n)
            break;
    }
    return filled_ >= n;
}

void FileReader::readAt(uint64_t offset, void* out, size_t size) const
{
    if (offset > size_ || size > size_ - offset)
        fail(path_, "truncated: " + std::to_string(size) + " bytes at offset " + std::to_string(offset) +
                        " run past the end of the file (" + std::to_string(size_) + " bytes)");
    readExactly(fd_, offset, out, size, path_);
}

TemporaryFile::TemporaryFile(const std::string& directory, const std::string& purpose, size_t bufferBytes)
    : name_(purpose + " (temporary file in " + (directory.empty() ? std::string(".") : directory) + ")")
{
    const std::string folder = directory.empty() ? std::string(".") : directory;
#ifdef O_TMPFILE
    fd_ = ::open(folder.c_str(), O_TMPFILE | O_RDWR | O_CLOEXEC, 0600);
#endif
    if (fd_ < 0) {
        std::string pattern = folder + "/.penumbra-tmp-XXXXXX";
        std::vector<char> name(pattern.begin(), pattern.end());
        name.push_back('\0');
        fd_ = ::mkstemp(name.data());
        if (fd_ >= 0)
            ::unlink(name.data());
    }
    if (fd_ < 0)
        fail(folder, std::string("cannot create a temporary file for ") + purpose + ": " + std::strerror(errno));
    buffer_.resize(std::max<size_t>(bufferBytes, 4096));
}

TemporaryFile::~TemporaryFile()
{
    if (fd_ >= 0)
        ::close(fd_);
}

void TemporaryFile::append(const void* data, size_t size)
{
    const uint8_t* bytes = static_cast<const uint8_t*>(data);
    if (buffer_.empty() && size > 0)
        fail(name_, "internal error: append after finish");
    while (size > 0) {
        if (used_ == buffer_.size())
            flush();
        const size_t take = std::min(size, buffer_.size() - used_);
        std::memcpy(buffer_.data() + used_, bytes, take);
        used_ += take;
        bytes += take;
        size -= take;
    }
}

void TemporaryFile::flush()
{
    size_t done = 0;
    while (done < used_) {
        ssize_t n = ::pwrite(fd_, buffer_.data() + done, used_ - done, off_t(flushed_ + done));
        if (n < 0 && errno == EINTR)
            continue;
        if (n <= 0)
            fail(name_, std::string("write failed: ") + std::strerror(errno));
        done += size_t(n);
    }
    flushed_ += used_;
    used_ = 0;
}

void TemporaryFile::readAt(uint64_t offset, void* out, size_t size)
{
    if (offset + size > flushed_)
        flush();
    if (offset > flushed_ || size > flushed_ - offset)
        fail(name_, "internal error: read past the end of a temporary file");
    readExactly(fd_, offset, out, size, name_);
}

void TemporaryFile::finish()
{
    flush();
    std::vector<uint8_t>().swap(buffer_);
}

} // namespace penumbra
